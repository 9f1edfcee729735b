"""Publishes a test image and an organized point cloud, like a robot's camera.  For tests.

``python camera_publisher.py RATE [COUNT [WIDTH HEIGHT]]``: frames on
``/multisense/left/image_color`` (bgr8 WIDTH x HEIGHT, default 320 x 240, smooth
gradients) and ``/multisense/points`` (a quarter of that, xyz + rgb), each
stamped, ``COUNT`` times (0, the default: forever), from when both topics have a
subscriber (or after 10 s); and a latched
``/robot_description_semantic``.  Prints ``published N`` after each frame.
"""

import sys
import time

import numpy as np
import rospy
from sensor_msgs.msg import Image, PointCloud2, PointField
from std_msgs.msg import String


def image(seq: int, width: int, height: int) -> Image:
    yy, xx = np.mgrid[0:height, 0:width]
    pixels = np.stack([(xx + seq) % 256, yy * 255 // height, (xx + yy) % 256], -1)
    msg = Image(height=height, width=width, encoding="bgr8", step=width * 3,
                data=pixels.astype(np.uint8).tobytes())
    msg.header.frame_id, msg.header.seq = "left_camera_optical_frame", seq
    msg.header.stamp = rospy.Time.now()
    return msg


def cloud(seq: int, width: int, height: int) -> PointCloud2:
    yy, xx = np.mgrid[0:height, 0:width].astype(np.float32)
    points = np.zeros((height, width, 4), np.float32)
    points[..., 0], points[..., 1], points[..., 2] = xx / 40, yy / 40, 2.0 + 0.01 * seq
    points[..., 3] = np.frombuffer(np.full(height * width, 0x00FF8000, np.uint32).tobytes(),
                                   np.float32).reshape(height, width)
    fields = [PointField("x", 0, PointField.FLOAT32, 1), PointField("y", 4, PointField.FLOAT32, 1),
              PointField("z", 8, PointField.FLOAT32, 1),
              PointField("rgb", 12, PointField.FLOAT32, 1)]
    msg = PointCloud2(height=height, width=width, fields=fields, is_bigendian=False,
                      point_step=16, row_step=16 * width, is_dense=True, data=points.tobytes())
    msg.header.frame_id, msg.header.seq = "head_hokuyo_frame", seq
    msg.header.stamp = rospy.Time.now()
    return msg


def main() -> int:
    rate, count = float(sys.argv[1]), int(sys.argv[2]) if len(sys.argv) > 2 else 0
    width, height = (int(sys.argv[3]), int(sys.argv[4])) if len(sys.argv) > 4 else (320, 240)
    rospy.init_node("test_camera")
    images = rospy.Publisher("/multisense/left/image_color", Image, queue_size=2)
    clouds = rospy.Publisher("/multisense/points", PointCloud2, queue_size=2)
    latched = rospy.Publisher("/robot_description_semantic", String, queue_size=1, latch=True)
    latched.publish(String("<robot name='walkman'/>"))
    # Frames published before a subscriber connects are lost to no one's fault but ROS's
    # (a benchmark would count them against the link): wait for one, up to 10 s.
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline and not rospy.is_shutdown() and \
            min(images.get_num_connections(), clouds.get_num_connections()) == 0:
        time.sleep(0.05)
    ticker = rospy.Rate(rate)
    seq = 0
    while not rospy.is_shutdown() and (count == 0 or seq < count):
        seq += 1
        images.publish(image(seq, width, height))
        clouds.publish(cloud(seq, width // 4, height // 4))
        print(f"published {seq}", flush=True)
        ticker.sleep()
    rospy.sleep(1.0)
    return 0


if __name__ == "__main__":
    sys.exit(main())
