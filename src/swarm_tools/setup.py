"""ament_python package swarm_tools (also pip-installable)."""
from setuptools import find_packages, setup

package_name = 'swarm_tools'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/config', ['config/record_qos_overrides.yaml']),
        # ros2 launch swarm_tools swarm.launch.py (after colcon build; the logic: swarm_tools.run.launch_description)
        ('share/' + package_name + '/launch', ['launch/swarm.launch.py']),
    ],
    package_data={package_name: ['live/foxglove_layout.json']},
    include_package_data=True,
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='homotopy-swarm developers',
    maintainer_email='dev@homotopy-swarm.invalid',
    description='Launcher, MCAP recorder, replay and reports for homotopy-swarm.',
    license='Apache-2.0',
    entry_points={'console_scripts': [
        'swarm = swarm_tools.cli:main',
        'swarm_record = swarm_tools.bags.record:main',
        'swarm_report = swarm_tools.bags.report:main',
        'swarm_play = swarm_tools.bags.play:main',
        'swarm_view = swarm_tools.live.view:main',
    ],
        # the fixtures ros_domain and swarm for users' own tests (swarm_tools.pytest_plugin)
        'pytest11': ['swarm_tools = swarm_tools.pytest_plugin']},
)
