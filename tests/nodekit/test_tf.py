"""The /tf builder: the robot's links in the pelvis frame, a preview's under its prefix."""

import numpy as np

from nodekit.tf import tf_message
from walkman.control.kinematics import Kinematics
from walkman.model.description import home_posture, walkman


def test_a_preview_hangs_its_links_under_the_prefix_from_the_robot_s_pelvis():
    robot = walkman()
    posture = home_posture(robot)
    q = np.array([posture[name] for name in robot.joint_names])
    placements = Kinematics().link_placements(q)
    plain = tf_message(placements, now=None)
    ghost = tf_message(placements, now=None, prefix="preview")
    assert {t.header.frame_id for t in plain.transforms} == {"pelvis"}
    assert "l_hand" in {t.child_frame_id for t in plain.transforms}
    root, *links = ghost.transforms
    assert (root.header.frame_id, root.child_frame_id) == ("pelvis", "preview/pelvis")
    assert root.transform.rotation.w == 1.0 and root.transform.translation.x == 0.0
    assert {t.header.frame_id for t in links} == {"preview/pelvis"}
    assert {t.child_frame_id for t in links} == {f"preview/{t.child_frame_id}"
                                                 for t in plain.transforms}
