"""What the telemetry rostests share: a log in VESC Tool's layout published as VESC-like messages,
the package's pmsm_tool, and waiting for the estimate of a stamp."""
import time

import roslib.packages
import rospy
from ros_wait import wait_for

from pmsm_param_id.msg import TestVescStateStamped


def publish_vesc_log(topic, log, pause=0.0, pause_every=1):
    """Publishes every row of `log` (pmsm_tool simulate --format vesc) on `topic` once a subscriber
    is there, sleeping `pause` seconds after every `pause_every` rows; returns the last stamp (None
    where nobody subscribed within 30 s)."""
    pub = rospy.Publisher(topic, TestVescStateStamped, queue_size=10000)
    deadline = time.time() + 30
    while pub.get_num_connections() == 0 and time.time() < deadline:
        time.sleep(0.1)
    if pub.get_num_connections() == 0:
        return None
    time.sleep(0.5)
    with open(log) as f:
        header = f.readline().strip().split(";")
        rows = [dict(zip(header, (float(c) for c in line.strip().split(";")))) for line in f if line.strip()]
    last = None
    for k, row in enumerate(rows):
        m = TestVescStateStamped()
        last = rospy.Time.from_sec(row["ms_today"] * 1e-3)
        m.header.stamp = last
        m.state.avg_vd, m.state.avg_vq = row["d_axis_voltage"], row["q_axis_voltage"]
        m.state.avg_id, m.state.avg_iq = row["d_axis_current"], row["q_axis_current"]
        m.state.speed = row["erpm"]
        m.state.voltage_input = row["input_voltage"]
        pub.publish(m)
        if pause > 0 and k % pause_every == pause_every - 1:
            time.sleep(pause)
    return last


def tool():
    """The pmsm_tool binary of this package."""
    found = roslib.packages.find_node("pmsm_param_id", "pmsm_tool")
    if not found:
        raise RuntimeError("pmsm_tool not built")
    return found[0]


def wait_for_estimate_of(estimates, last, timeout=60.0):
    """Waits until the last of `estimates` (ParameterEstimate messages) is of the stamp `last`."""
    return wait_for(lambda: estimates and abs((estimates[-1].header.stamp - last).to_sec()) < 1e-6, timeout, 0.2)
