"""ament_python package swarm_core (also pip-installable)."""
from setuptools import find_packages, setup

package_name = 'swarm_core'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
    ],
    package_data={package_name: ['scenarios/*.yaml']},
    include_package_data=True,
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='homotopy-swarm developers',
    maintainer_email='dev@homotopy-swarm.invalid',
    description='Morgan and Schwartz swarm laws in pure numpy: integrator, scenarios, metrics, batch engine (no ROS).',
    license='Apache-2.0',
)
