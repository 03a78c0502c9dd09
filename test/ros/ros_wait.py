"""What the rostest check nodes share: waiting for a condition while ROS runs."""
import time

import rospy


def wait_for(predicate, timeout=60.0, poll=0.05):
    """True once predicate() is, False after timeout seconds (or when ROS shuts down)."""
    deadline = time.time() + timeout
    while time.time() < deadline and not rospy.is_shutdown():
        if predicate():
            return True
        time.sleep(poll)
    return False
