"""ament_python package swarm_agent (also pip-installable)."""
from setuptools import find_packages, setup

package_name = 'swarm_agent'

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
    description='AgentNode: one swarm agent as an rclpy node integrating its own Frenet frame.',
    license='Apache-2.0',
    entry_points={'console_scripts': ['swarm_agent = swarm_agent.agent_node:main',
                                  'swarm_agent_container = swarm_agent.container_node:main']},
)
