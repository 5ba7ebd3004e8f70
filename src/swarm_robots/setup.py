"""ament_python package swarm_robots (also pip-installable)."""
from setuptools import find_packages, setup

package_name = 'swarm_robots'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
    ],
    package_data={package_name: []},
    include_package_data=True,
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='homotopy-swarm developers',
    maintainer_email='dev@homotopy-swarm.invalid',
    description='Robots for the swarm: a robot description, a diff_drive_controller emulation and a MuJoCo world.',
    license='Apache-2.0',
    entry_points={'console_scripts': ['swarm_robots = swarm_robots.mujoco_world_node:main'],
                  # the robot engine of studies, by name (swarm_core.engine.registry)
                  'swarm_core.engines': ['robots = swarm_robots.engine:simulate']},
)
