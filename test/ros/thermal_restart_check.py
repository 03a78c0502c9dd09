#!/usr/bin/env python3
"""Test node of thermal_restart.test: an identifier restarted mid-run on a hot motor."""
import os
import signal
import subprocess
import sys
import tempfile
import unittest

import rosgraph
import rospkg
import rospy
import rostest
from ros_wait import wait_for

from pmsm_param_id.msg import ActiveAlarms, ElectricalParameters, ParameterEstimate

RESTART_AT = 2.0  # [s of drive time]: the winding is about 80 K above the cold start then
END = 4.9  # [s of drive time]: the scenario runs 5 s (at a quarter of real time)


class ThermalRestart(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("thermal_restart_check")
        cls.tmp = tempfile.mkdtemp(prefix="pmsm_thermal_")
        cls.state = os.path.join(cls.tmp, "rls_thermal.yaml")
        cls.config = os.path.join(rospkg.RosPack().get_path("pmsm_param_id"), "config", "identifiers",
                                  "cold_start.yaml")
        cls.truth = []  # (stamp [s], winding temperature [degC])
        cls.estimates = {"first": [], "kept": [], "forgetful": []}
        cls.alarms = {"first": [], "kept": []}  # every ActiveAlarms an early subscriber received
        for name in cls.alarms:
            rospy.Subscriber("/%s/active_alarms" % name, ActiveAlarms, cls.alarms[name].append)
        rospy.Subscriber("/drive/true_parameters", ElectricalParameters,
                         lambda m: cls.truth.append((m.header.stamp.to_sec(), m.winding_temperature)))
        for name in cls.estimates:
            rospy.Subscriber("/%s/estimate" % name, ParameterEstimate, cls.estimates[name].append)
        cls.procs = {}

    @classmethod
    def start(cls, name, state):
        cmd = ["rosrun", "pmsm_param_id", "identifier", "__name:=" + name, "_method:=rls", "_config:=" + cls.config,
               "_publish_period:=0.01", "samples_batch:=/drive/samples_batch"]
        if state:
            cmd.append("_thermal_state:=" + state)
        cls.procs[name] = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)

    @classmethod
    def stop(cls, name):
        p = cls.procs.pop(name)
        p.send_signal(signal.SIGINT)
        p.wait(timeout=20)

    @classmethod
    def tearDownClass(cls):
        for name in list(cls.procs):
            cls.stop(name)

    def wait_for(self, predicate, timeout):
        return wait_for(predicate, timeout, poll=0.02)

    def drive_time(self):
        return self.truth[-1][0] - self.truth[0][0] if self.truth else 0.0

    @staticmethod
    def subscribed(names, topic="/drive/samples_batch"):
        """True once every node in names subscribes to topic (registered with the master)."""
        state = rosgraph.Master("/thermal_restart_check").getSystemState()
        subscribers = next((nodes for t, nodes in state[1] if t == topic), [])
        return all("/" + n in subscribers for n in names)

    def truth_at(self, stamp):
        return min(self.truth, key=lambda x: abs(x[0] - stamp))[1]

    def test_a_restart_on_a_hot_motor_keeps_the_cold_references(self):
        self.start("first", self.state)  # the simulator waits for it
        self.assertTrue(self.wait_for(lambda: os.path.exists(self.state), 60), "the cold start wrote no thermal state")
        with open(self.state) as f:
            text = f.read()
        self.assertIn("R_s_at_reference:", text)
        self.assertIn("reference_temperature: 20", text)
        self.assertTrue(self.wait_for(lambda: self.drive_time() >= RESTART_AT, 60), "the drive did not run")
        self.stop("first")
        hot = self.truth[-1][1]
        self.assertGreater(hot, 80.0)  # the motor is hot when the identifiers start again
        self.start("kept", self.state)
        self.start("forgetful", os.path.join(self.tmp, "absent", "none.yaml"))
        # The drive does not wait for the restarted identifiers: on a loaded machine they may take a
        # second or more to start, so the time they have is measured, not assumed.
        self.assertTrue(self.wait_for(lambda: self.subscribed(["kept", "forgetful"]), 30),
                        "the restarted identifiers did not subscribe to the samples")
        restarted = self.drive_time()
        self.assertLess(restarted, END - 1.2, "the identifiers subscribed at %.2f s of drive time, too late to "
                        "read a winding temperature before the run ends" % restarted)
        self.assertTrue(self.wait_for(lambda: self.drive_time() >= END, 60), "the drive did not finish")
        end_stamp = self.truth[-1][0]
        # Wait until the identifier has caught up with the drive (not a fixed sleep).
        self.wait_for(lambda: self.estimates["kept"] and self.estimates["kept"][-1].header.stamp.to_sec() >=
                      end_stamp - 0.05, 20)
        kept = [e for e in self.estimates["kept"] if e.winding_temperature == e.winding_temperature]
        print("restart at %.1f degC (%.2f s); kept: %d estimates, %d with a temperature" % (
            hot, restarted, len(self.estimates["kept"]), len(kept)), file=sys.stderr)
        # (From the restart to the end, the slow window's first second included: some tens of
        # estimates with a temperature.)
        self.assertGreater(len(kept), 10, "the restarted identifier reported %d winding temperatures in %d "
                           "estimates (subscribed at %.2f s of drive time)" % (len(kept), len(self.estimates["kept"]),
                                                                              restarted))
        last = kept[-1]
        truth = self.truth_at(last.header.stamp.to_sec())
        forgetful = [e for e in self.estimates["forgetful"] if e.winding_temperature == e.winding_temperature]
        print("restart at %.1f degC; kept: %.1f +- %.1f K, forgetful: %s, truth %.1f degC" % (
            hot, last.winding_temperature, last.winding_temperature_uncertainty,
            "%.1f" % forgetful[-1].winding_temperature if forgetful else "none", truth), file=sys.stderr)
        self.assertLessEqual(abs(last.winding_temperature - truth), last.winding_temperature_uncertainty,
                             "%.1f degC +- %.1f K against %.1f degC" % (last.winding_temperature,
                                                                       last.winding_temperature_uncertainty, truth))
        # Without the kept references the same restart takes the hot motor for a cold one.
        self.assertTrue(forgetful)
        self.assertGreater(abs(forgetful[-1].winding_temperature - self.truth_at(forgetful[-1].header.stamp.to_sec())),
                           40.0)

    def test_active_alarms_are_latched_for_a_late_subscriber(self):
        msgs = []
        self.assertTrue(self.wait_for(lambda: "first" in self.procs or "kept" in self.procs, 60))
        name = "first" if "first" in self.procs else "kept"
        self.assertTrue(self.wait_for(lambda: self.alarms[name], 20), "no active_alarms from /%s" % name)
        sub = rospy.Subscriber("/%s/active_alarms" % name, ActiveAlarms, msgs.append)
        self.assertTrue(self.wait_for(lambda: msgs, 20), "no latched active_alarms")
        sub.unregister()
        # A late subscriber gets the list as it stands: the last one an early subscriber received (empty
        # while the motor is healthy; once the restarted identifier reads the winding above the
        # configured limit, that alarm).
        self.assertEqual(msgs[-1].method, "rls")
        self.assertEqual([a.kind for a in msgs[-1].active], [a.kind for a in self.alarms[name][-1].active])
        self.assertTrue(set(a.kind for a in msgs[-1].active) <= {"winding_over_temperature"},
                        [a.text for a in msgs[-1].active])
        self.assertEqual(list(self.alarms[name][0].active), [])  # the list each identifier latches at start


if __name__ == "__main__":
    rostest.rosrun("pmsm_param_id", "thermal_restart", ThermalRestart)
