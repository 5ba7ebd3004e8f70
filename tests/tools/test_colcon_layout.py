"""The layout colcon and ``ros2 run`` need from every package (no ROS, no build): a setup.cfg
that installs its scripts to ``lib/<package>``, its ament resource marker and package.xml, and
console scripts exactly where a package has executables.  The colcon build and ``ros2 run`` of
the packages: tests/tools/ros/test_colcon_build.py.
"""
from tests.helpers import PACKAGES, ROOT, console_scripts

LIBRARIES = ('swarm_core', 'swarm_ros')     # no executables: the `swarm` command is swarm_tools'


def test_every_package_installs_its_scripts_to_lib_package():
    """The setup.cfg ament_python packages need."""
    import configparser
    for pkg in PACKAGES:
        cfg = configparser.ConfigParser(interpolation=None)
        assert cfg.read(ROOT / 'src' / pkg / 'setup.cfg'), pkg
        assert cfg['develop']['script_dir'] == f'$base/lib/{pkg}'
        assert cfg['install']['install_scripts'] == f'$base/lib/{pkg}'
        assert (ROOT / 'src' / pkg / 'resource' / pkg).is_file()
        assert f'<name>{pkg}</name>' in (ROOT / 'src' / pkg / 'package.xml').read_text()
        assert bool(console_scripts(pkg)) == (pkg not in LIBRARIES), pkg
