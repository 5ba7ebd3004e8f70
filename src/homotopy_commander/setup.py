"""ament_python package homotopy_commander (also pip-installable)."""
from setuptools import find_packages, setup

package_name = 'homotopy_commander'

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
    description='CommanderNode: homotopy parameter schedules and ramps, leader steering programs, and a CLI.',
    license='Apache-2.0',
    entry_points={'console_scripts': ['homotopy_commander = homotopy_commander.commander_node:main']},
)
