"""Walk-Man software architecture, reproduced as runnable Python middleware."""

from setuptools import find_packages, setup

setup(
    name="walkman-architecture",
    version="0.1.0",
    description="Walk-Man humanoid software architecture: yarp_lite, GYM, HAL, network bridge, "
                "ROS pilot nodes",
    python_requires=">=3.11",
    packages=find_packages(include=["yarp_lite*", "walkman*", "bridge*", "netem*", "rosnodes*", "system*", "nodekit*", "pilot*"]),
    package_data={"": ["*.xml", "*.xsd", "*.ini", "*.urdf", "*.msg", "*.srv"],
                  # the robot's models, configurations, contexts and layouts (walkman.MODELS_DIR)
                  "walkman": ["models/*.xml", "models/*.ini", "models/*.urdf", "models/contexts/*/*.ini"],
                  # the ROS packages (message definitions, launch files) the nodes need
                  "rosnodes": ["walkman_msgs/package.xml", "walkman_msgs/msg/*.msg",
                               "walkman_msgs/srv/*.srv", "walkman_launch/package.xml",
                               "walkman_launch/launch/*.launch", "walkman_launch/scripts/*"]},
    include_package_data=True,
    install_requires=["numpy"],
    extras_require={
        "sim": ["mujoco", "pin"],
        "bridge": ["lxml", "opencv-python-headless"],
        "test": ["pytest", "pytest-xdist", "hypothesis"],
    },
    entry_points={
        "console_scripts": [
            "yarp-lite=yarp_lite.cli:main",
            "walkman-hal=walkman.hal.server:main",
            "walkman-module=walkman.gym.supervisor:main",
            "walkman-bridge=bridge.main:main",
            "walkman-netem=netem.emulation:main",
            "walkman-pilot-gateway=rosnodes.gateway:main",
            "walkman-perception=rosnodes.perception:main",
            "walkman-joint-state=rosnodes.joint_state:main",
            "walkman-ros-clock=rosnodes.ros_clock:main",
            "walkman-compare=system.compare:main",
            "walkman-pc=system.pc:main",
            "walkman-main-job=system.mainjob:main",
            "walkman-chaos=system.chaos:main",
            "walkman-pilot=pilot.app:main",
        ],
    },
)
