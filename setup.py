# Used by catkin_python_setup(); do not run by hand.
from catkin_pkg.python_setup import generate_distutils_setup
from setuptools import setup

setup(**generate_distutils_setup(packages=['ros_hrc', 'ros_hrc.pomdp', 'ros_hrc.world',
                                           'ros_hrc.link', 'ros_hrc.loop', 'ros_hrc.nodes',
                                           'ros_hrc.processes', 'ros_hrc.experiment',
                                           'ros_hrc.tasks', 'ros_hrc.agents',
                                           'ros_hrc.commands'],
                                 package_dir={'': 'src'}))
