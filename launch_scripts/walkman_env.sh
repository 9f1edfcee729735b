# Source me (bash): ROS tools and Python then find this project's messages and programs.
#   source launch_scripts/walkman_env.sh
#   rosmsg show walkman_msgs/Status
#   rostopic pub -1 /gaze_control/switch walkman_msgs/Switch "command: start"
_walkman_root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
export ROS_PACKAGE_PATH="$_walkman_root/rosnodes:$_walkman_root/build/ros/share:/usr/share${ROS_PACKAGE_PATH:+:$ROS_PACKAGE_PATH}"
export PYTHONPATH="$_walkman_root/build/ros/lib:$_walkman_root${PYTHONPATH:+:$PYTHONPATH}"
export PATH="$_walkman_root/.venv/bin:$PATH"
export ROS_MASTER_URI="${ROS_MASTER_URI:-http://127.0.0.1:11311}"
export ROS_IP="${ROS_IP:-127.0.0.1}"
unset _walkman_root
