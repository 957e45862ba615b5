from glob import glob

from setuptools import find_packages, setup

PACKAGE = 'uav_comm_planner'

ROS_JAZZY = [
    'ros-jazzy-rclpy>=7.1,<8',
    'ros-jazzy-common-interfaces>=5.3,<6',
    'ros-jazzy-std-srvs>=5.3,<6',
    'ros-jazzy-rmw-fastrtps-cpp>=8.4,<9',
]

setup(
    name=PACKAGE,
    # Keep equal to package.xml's <version> (a test checks); `uav-comm-planner --version`
    # reads it back from the installed metadata.
    version='0.1.0',
    # The package only: devtools/ (SITL launchers, benchmark, docgen) and test/ stay out.
    packages=find_packages(include=[PACKAGE, f'{PACKAGE}.*']),
    # The airframes measured for this package, read by name (vehicle/airframe.py).
    package_data={f'{PACKAGE}.vehicle': ['airframes/*.yaml']},
    data_files=[
        ('share/ament_index/resource_index/packages', [f'resource/{PACKAGE}']),
        (f'share/{PACKAGE}', ['package.xml']),
        (f'share/{PACKAGE}/config', glob('config/*.yaml')),
        (f'share/{PACKAGE}/launch', glob('launch/*.launch.py')),
        (f'share/{PACKAGE}/rviz', glob('rviz/*.rviz')),
    ],
    python_requires='>=3.10',
    install_requires=[
        'numpy>=1.26,<3',
        'cvxpy>=1.5,<2',
        'clarabel>=0.11,<0.12',
        'scipy>=1.11,<2',
        'pymavlink>=2.4.40,<3',
        'pymap3d>=3.0,<4',
        # Airframe files (the propulsion model of the vehicle, vehicle/airframe.py).
        'pyyaml>=6,<7',
    ],
    extras_require={
        # In a ROS 2 Jazzy workspace these come from the distribution (rosdep);
        # outside one, the PyPI wheels of Jazzy provide them.
        'ros': ROS_JAZZY,
        'plots': ['matplotlib>=3.8,<4', 'contourpy>=1.2,<2'],
        # Serial links to a vehicle (mavlink_url /dev/ttyACM0,115200): pymavlink opens them
        # with pyserial.
        'serial': ['pyserial>=3.5,<4'],
        # PyYAML (RViz configuration and launch parameters in the tests) also comes with
        # the ROS wheels; named here so that the tests do not rely on that.
        # colcon (with its ROS and setup.py extensions) and rosdep: the tests build the
        # package with colcon and resolve package.xml's keys with rosdep, as a ROS user does.
        # colcon-core 0.21 caps setuptools below 80, whose develop lost --editable (the
        # route of --symlink-install).
        'test': ['pytest>=8,<10', 'pyyaml>=6,<7', 'hypothesis>=6.100,<7',
                 'colcon-core>=0.21,<1', 'colcon-ros>=0.5,<1',
                 'colcon-python-setup-py>=0.2.9,<1', 'rosdep>=0.25,<1'],
        # Monte Carlo studies (uav-comm-planner montecarlo): Dask for the workers, pyarrow for
        # the Parquet table, matplotlib for the figures. dask and distributed are released
        # together under the same calendar version.
        'study': ['dask>=2024.8,<2027', 'distributed>=2024.8,<2027', 'pyarrow>=15,<27',
                  'matplotlib>=3.8,<4'],
    },
    zip_safe=True,
    maintainer='uav_comm_planner maintainers',
    maintainer_email='maintainers@uav-comm-planner.invalid',
    description='Joint transmit-power and trajectory planning for a communication UAV.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            f'planner = {PACKAGE}.ros.launcher:main',
            f'send_ground_nodes = {PACKAGE}.ros.send_ground_nodes:main',
            f'uav-comm-planner = {PACKAGE}.tools.cli:main',
        ],
    },
)
