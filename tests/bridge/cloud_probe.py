"""Prints what arrives on the pilot side: ``cloud SEQ NAN_FRACTION`` and ``image SEQ BLACK_FRACTION``.

For the bridge tests; run with the pilot's ROS_MASTER_URI.
"""

import sys

import numpy as np
import rospy
from sensor_msgs.msg import Image, PointCloud2


def on_cloud(msg: PointCloud2) -> None:
    points = np.frombuffer(msg.data, np.float32).reshape(-1, msg.point_step // 4)
    print(f"cloud {msg.header.seq} {np.isnan(points[:, 0]).mean():.4f} "
          f"dense={int(msg.is_dense)}", flush=True)


def on_image(msg: Image) -> None:
    pixels = np.frombuffer(msg.data, np.uint8).reshape(msg.height, msg.width, 3)
    print(f"image {msg.header.seq} {(pixels.max(axis=2) == 0).mean():.4f}", flush=True)


def main() -> int:
    rospy.init_node("test_cloud_probe")
    rospy.Subscriber("/multisense/points", PointCloud2, on_cloud, queue_size=10)
    rospy.Subscriber("/multisense/left/image_color", Image, on_image, queue_size=10)
    print("probe ready", flush=True)
    rospy.spin()
    return 0


if __name__ == "__main__":
    sys.exit(main())
