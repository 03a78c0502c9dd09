#!/usr/bin/env python3
"""Test node of telemetry_bridge.test: a VESC-like stream through the bridge and the identifier
gives identify's estimate of the same log."""
import json
import math
import os
import subprocess
import tempfile
import unittest

import rospkg
import rospy
import rostest

from pmsm_param_id.msg import ParameterEstimate
from vesc_stream import publish_vesc_log, tool, wait_for_estimate_of

PARAMETERS = ("R_s", "L_d", "L_q", "psi_f")
STATUS = {0: "no_data", 1: "identified", 2: "not_excited", 3: "poor_fit", 4: "at_bound", 5: "implausible",
          6: "not_converged"}


class TelemetryBridge(unittest.TestCase):
    def test_a_bridge_misconfigured_stops_with_one_line_and_exit_2(self):
        cases = [(["_speed_unit:=rpm"], "set ~pole_pairs"),
                 (["_speed_unit:=furlongs"], "~speed_unit: 'furlongs' is not one of"),
                 (["_fields:={u_d: a, u_q: b, i_d: c, i_q: d, omega_e: e, torque: f}"], "unknown key(s) torque"),
                 (["_fields:={u_d: a, u_q: b, i_d: c, i_q: d}"], "missing omega_e"),
                 (["_fields:={u_d: 'a[x]', u_q: b, i_d: c, i_q: d, omega_e: e}"], "index 'x' is not a number")]
        for k, (args, message) in enumerate(cases):
            r = subprocess.run(["rosrun", "pmsm_param_id", "telemetry_bridge.py", "__name:=bad_bridge_%d" % k] + args,
                               capture_output=True, text=True, timeout=60)
            self.assertEqual(r.returncode, 2, (args, r.stdout, r.stderr))
            self.assertIn(message, r.stdout + r.stderr, args)

    def test_a_vesc_like_stream_gives_identifys_estimate_of_the_same_log(self):
        tmp = tempfile.mkdtemp(prefix="pmsm_bridge_")
        log, out = os.path.join(tmp, "vesc.csv"), os.path.join(tmp, "vesc.json")
        scenario = os.path.join(rospkg.RosPack().get_path("pmsm_param_id"), "config", "scenarios",
                                "telemetry_duty_cycle.yaml")
        r = subprocess.run([tool(), "simulate", "--scenario", scenario, "--csv", log, "--duration", "40",
                            "--telemetry-period", "0.02", "--format", "vesc", "--clock-start", "1000"],
                           capture_output=True, text=True)
        self.assertEqual(r.returncode, 0, r.stderr)
        r = subprocess.run([tool(), "identify", "--csv", log, "--format", "vesc", "--json", out],
                           capture_output=True, text=True)
        self.assertEqual(r.returncode, 0, r.stderr)
        with open(out) as f:
            expected = json.load(f)
        self.assertEqual(expected["method"], "steady_state")

        estimates = []
        rospy.Subscriber("/telemetry/identifier/estimate", ParameterEstimate, estimates.append)
        last = publish_vesc_log("/vesc/sensors/core", log, pause=0.01, pause_every=50)
        self.assertIsNotNone(last, "the bridge never subscribed")
        # The identifier publishes the fit of every sample once the stream pauses.
        wait_for_estimate_of(estimates, last)
        self.assertTrue(estimates, "no estimate from the identifier")
        final = estimates[-1]
        self.assertLess(abs((final.header.stamp - last).to_sec()), 1e-6, "the last estimate is not of the last sample")
        self.assertEqual(final.method, "steady_state")
        for k, p in enumerate(PARAMETERS):
            self.assertEqual(STATUS[final.status[k]], expected["status"][p], (p, final.status_reason[k]))
            self.assertTrue(math.isclose(getattr(final, p), expected[p], rel_tol=1e-6),
                            (p, getattr(final, p), expected[p]))
        self.assertEqual(expected["status"]["L_q"], "identified")
        self.assertEqual(expected["status"]["psi_f"], "identified")


if __name__ == "__main__":
    rospy.init_node("telemetry_bridge_check")
    rostest.rosrun("pmsm_param_id", "telemetry_bridge", TelemetryBridge)
