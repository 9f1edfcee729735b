import time
from walkman.model.mjcf import PILOT_POSES
WHEEL = PILOT_POSES["car"]


def test_wheel_follows(task_at):
    drive = task_at("car", "drc_drive")
    drive.command(WHEEL, "ready")
    for command, state in (("reach", "reached"), ("approach", "approached"),
                           ("grasp", "grasped"), ("drive", "drive")):
        drive.command(command, state)
    start = drive.scene.prop("steering")
    rows = []
    def look(what):
        time.sleep(1.5)
        rows.append((what, round(drive.pilot.data()[4], 3), round(drive.scene.prop("steering") - start, 3)))
    for command in ("turn_left 0.5", "turn_right 0.5", "turn_left 0.42", "rotate_foot",
                    "accelerate 1 1", "move_away_foot"):
        drive.send("command", command)
        from harness import wait_until
        wait_until(lambda: drive.pilot.state() != "drive", 20, message=command)
        drive.pilot.wait_state("drive", 60)
        look(command)
    drive.command("ungrasp", "ungrasped")
    rows.append(("ungrasp", None, round(drive.scene.prop("steering") - start, 3)))
    drive.command("move_away_hand", "moved_away_hand")
    time.sleep(2)
    rows.append(("move_away_hand", None, round(drive.scene.prop("steering") - start, 3)))
    for r in rows: print("ROW", *r)
