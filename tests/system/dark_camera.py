"""Publishes a head camera's frames with a black sky and a cloud with no depth there.  For tests.

``python dark_camera.py RATE``: ``/multisense/left/image_color`` (bgr8 320 x 240,
its top 40 % exactly black, a grey gradient below) and ``/multisense/points``
(80 x 60, the points of the top 40 % NaN: no depth) as the lab's perception
node gives them straight to the pilot's roscore -- no bridge, nothing lost.
"""

import sys

import numpy as np
import rospy
from sensor_msgs.msg import Image, PointCloud2, PointField

SKY = 0.4


def image(width: int = 320, height: int = 240) -> Image:
    yy, xx = np.mgrid[0:height, 0:width]
    pixels = np.stack([60 + xx * 120 // width, 60 + yy * 120 // height,
                       np.full_like(xx, 90)], -1).astype(np.uint8)
    pixels[:int(SKY * height)] = 0
    msg = Image(height=height, width=width, encoding="bgr8", step=3 * width,
                data=pixels.tobytes())
    msg.header.frame_id = "left_camera_optical_frame"
    return msg


def cloud(width: int = 80, height: int = 60) -> PointCloud2:
    yy, xx = np.mgrid[0:height, 0:width].astype(np.float32)
    points = np.stack([xx / 40, yy / 40, np.full_like(xx, 2.0), np.zeros_like(xx)], -1)
    points[:int(SKY * height), :, :3] = np.nan
    fields = [PointField(name, 4 * i, PointField.FLOAT32, 1)
              for i, name in enumerate(("x", "y", "z", "rgb"))]
    msg = PointCloud2(height=height, width=width, fields=fields, point_step=16,
                      row_step=16 * width, is_dense=False, data=points.tobytes())
    msg.header.frame_id = "head_hokuyo_frame"
    return msg


def main() -> int:
    rospy.init_node("test_dark_camera")
    images = rospy.Publisher("/multisense/left/image_color", Image, queue_size=2)
    clouds = rospy.Publisher("/multisense/points", PointCloud2, queue_size=2)
    frame, points = image(), cloud()
    ticker = rospy.Rate(float(sys.argv[1]))
    while not rospy.is_shutdown():
        frame.header.stamp = points.header.stamp = rospy.Time.now()
        images.publish(frame)
        clouds.publish(points)
        ticker.sleep()
    return 0


if __name__ == "__main__":
    sys.exit(main())
