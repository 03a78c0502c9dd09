#!/usr/bin/env python3
"""Test node of telemetry_alarms.test: a heating motor's telemetry gives identify's winding
temperature of the same log, and the over-temperature alarm from telemetry."""
import json
import math
import os
import subprocess
import tempfile
import unittest

import rospkg
import rospy
import rostest

from pmsm_param_id.msg import ConditionEvent, ParameterEstimate
from ros_wait import wait_for
from vesc_stream import publish_vesc_log, tool, wait_for_estimate_of


class TelemetryAlarms(unittest.TestCase):
    def test_a_heating_motors_telemetry_raises_the_over_temperature_alarm(self):
        package = rospkg.RosPack().get_path("pmsm_param_id")
        tmp = tempfile.mkdtemp(prefix="pmsm_alarms_")
        log, out = os.path.join(tmp, "vesc.csv"), os.path.join(tmp, "vesc.json")
        config = os.path.join(package, "test", "ros", "telemetry_alarm.yaml")
        scenario = os.path.join(package, "config", "scenarios", "healthy_long_run.yaml")
        r = subprocess.run([tool(), "simulate", "--scenario", scenario, "--csv", log, "--duration", "250",
                            "--telemetry-period", "0.5", "--format", "vesc", "--clock-start", "1000"],
                           capture_output=True, text=True)
        self.assertEqual(r.returncode, 0, r.stderr)
        r = subprocess.run([tool(), "identify", "--csv", log, "--format", "vesc", "--config", config, "--json", out],
                           capture_output=True, text=True)
        self.assertEqual(r.returncode, 0, r.stderr)
        with open(out) as f:
            expected = json.load(f)
        self.assertIsNotNone(expected["winding_temperature"], "identify reports no winding temperature")
        self.assertGreater(expected["winding_temperature"], 40.0)

        estimates, events = [], []
        rospy.Subscriber("/hot/identifier/estimate", ParameterEstimate, estimates.append)
        rospy.Subscriber("/hot/identifier/events", ConditionEvent, events.append)
        # About 2.5 s of wall time: the node refits several times along the way.
        last = publish_vesc_log("/hot_vesc/sensors/core", log, pause=0.005)
        self.assertIsNotNone(last, "the bridge never subscribed")
        wait_for_estimate_of(estimates, last)
        self.assertTrue(estimates, "no estimate from the identifier")
        final = estimates[-1]
        self.assertLess(abs((final.header.stamp - last).to_sec()), 1e-6, "the last estimate is not of the last sample")
        self.assertTrue(math.isclose(final.winding_temperature, expected["winding_temperature"], rel_tol=1e-6),
                        (final.winding_temperature, expected["winding_temperature"]))
        self.assertTrue(math.isclose(final.winding_temperature_uncertainty, expected["winding_temperature_uncertainty"],
                                     rel_tol=1e-6))
        # The events come on their own topic: the last refit's may arrive after its estimate.
        wait_for(lambda: any(e.raised and e.kind == "winding_over_temperature" for e in events), 10.0)
        raised = [e for e in events if e.raised]
        self.assertTrue(any(e.kind == "winding_over_temperature" for e in raised), [(e.kind, e.text) for e in events])
        self.assertEqual({e.kind for e in raised}, {"winding_over_temperature"}, [(e.kind, e.text) for e in raised])


if __name__ == "__main__":
    rospy.init_node("telemetry_alarms_check")
    rostest.rosrun("pmsm_param_id", "telemetry_alarms", TelemetryAlarms)
