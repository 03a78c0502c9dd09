#!/usr/bin/env python3
"""Test node of identifier_node.test."""
import math
import random
import unittest

import rospy
import rostest
from ros_wait import wait_for
from diagnostic_msgs.msg import DiagnosticArray
from rosgraph_msgs.msg import Log

from std_srvs.srv import Trigger

from pmsm_param_id.msg import DriveSampleBatch, ElectricalParameters, ParameterEstimate
from pmsm_param_id.srv import SetPublishPeriod


class IdentifierNode(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("identifier_node_check")
        cls.estimates, cls.probe, cls.diag, cls.log = [], [], {}, []
        cls.truth = None
        rospy.Subscriber("/identifiers/fbdapso/estimate", ParameterEstimate, cls.estimates.append)
        rospy.Subscriber("/probe/estimate", ParameterEstimate, cls.probe.append)
        rospy.Subscriber("/drive/true_parameters", ElectricalParameters, lambda m: setattr(cls, "truth", m))
        rospy.Subscriber("/diagnostics", DiagnosticArray, cls.on_diag)
        rospy.Subscriber("/rosout", Log, cls.log.append)

    @classmethod
    def on_diag(cls, msg):
        for s in msg.status:
            cls.diag[s.name] = s

    def wait_for(self, predicate, timeout=60.0):
        return wait_for(predicate, timeout)

    def test_plant_and_identifier_converge_without_losing_samples(self):
        self.assertTrue(self.wait_for(lambda: rospy.has_param("/drive/samples_published")), "plant did not finish")
        published = rospy.get_param("/drive/samples_published")
        self.assertEqual(published, 3000)
        self.assertTrue(self.wait_for(lambda: self.estimates and self.estimates[-1].samples_used == published, 20),
                        "identifier did not process every sample")
        e, t = self.estimates[-1], self.truth
        for name in ("R_s", "L_d", "L_q", "psi_f"):
            self.assertLess(abs(getattr(e, name) / getattr(t, name) - 1.0), 0.01, name)
        self.assertTrue(all(e.identifiable))

    def batch(self, stamp, first_index, n=50, nan_at=None, period=1e-4):
        b = DriveSampleBatch()
        b.header.stamp = stamp
        b.sample_period = period
        b.first_index = first_index
        for k in range(n):
            b.u_d.append(-50.0 + math.sin(k))
            b.u_q.append(100.0)
            b.i_d.append(0.1 * math.cos(k))
            b.i_q.append(9.0)
            b.omega_e.append(418.9)
        if nan_at is not None:
            b.i_q[nan_at] = float("nan")
        return b

    def counters(self, name):
        status = self.diag.get(name)
        return {} if status is None else {kv.key: kv.value for kv in status.values}

    def test_bad_input_is_counted_and_reported_not_fatal(self):
        pub = rospy.Publisher("/probe_samples", DriveSampleBatch, queue_size=100)
        self.assertTrue(self.wait_for(lambda: pub.get_num_connections() > 0, 20))
        t0 = rospy.Time(5000.0)
        dt = rospy.Duration(50 * 1e-4)
        pub.publish(self.batch(t0, 0))
        pub.publish(self.batch(t0 + dt, 50, nan_at=7))           # one non-finite sample
        pub.publish(self.batch(t0 + dt * 3, 150))                # 50 samples lost: a gap
        bad = self.batch(t0 + dt * 4, 200)
        bad.i_d.pop()                                            # malformed: arrays of different lengths
        pub.publish(bad)
        pub.publish(self.batch(t0 + dt * 4, 200))
        # Stamped 0.9 periods early but continuing the index: stamp jitter, its times from the index.
        pub.publish(self.batch(t0 + dt * 5 - rospy.Duration(0.9e-4), 250))
        pub.publish(self.batch(t0, 0))                           # stamps go backwards: the bag looped
        name = "probe: identifier"
        self.assertTrue(self.wait_for(lambda: self.counters(name).get("time resets (stamps went backwards)") == "1", 30),
                        str(self.counters(name)))
        c = self.counters(name)
        self.assertEqual(c["samples skipped (non-finite)"], "1")
        self.assertEqual(c["samples dropped (index gaps)"], "50")
        self.assertEqual(c["malformed messages"], "1")
        self.assertEqual(c["time gaps"], "1")
        self.assertEqual(c["samples skipped (stamp too close)"], "0")
        self.assertEqual(c["monitor and map restarts (time resets, ~reset)"], "1")  # with the time reset
        self.assertEqual(c["samples received"], "300")
        self.assertEqual(self.diag[name].level, 1)  # WARN
        # Every good sample was used. This synthetic signal is no motor (no consistent inductance), so
        # no estimate is published at all rather than a made-up one; the diagnostics say so.
        self.assertTrue(self.wait_for(lambda: self.counters(name).get("samples used") == "299", 10),
                        str(self.counters(name)))
        self.assertTrue(all(math.isfinite(v) for p in self.probe for v in (p.R_s, p.L_d, p.L_q, p.psi_f)))
        # A stamp 4e9 s later (beyond ros::Duration's 2^31 s): a gap, not an abort.
        pub.publish(self.batch(rospy.Time(4000005000), 300))
        self.assertTrue(self.wait_for(lambda: self.counters(name).get("samples received") == "350", 10),
                        str(self.counters(name)))
        self.assertEqual(self.counters(name)["time gaps"], "2")
        # The warning for bad input holds for ~bad_input_hold (3 s here), then the data's own state
        # shows again; the counters keep the totals.
        self.assertIn("some input was bad", self.diag[name].message)
        self.assertTrue(self.wait_for(lambda: "some input was bad" not in self.diag[name].message, 10),
                        self.diag[name].message)
        self.assertEqual(self.counters(name)["time gaps"], "2")
        self.assertEqual(self.counters(name)["malformed messages"], "1")

    def test_reset_forgets_the_stream_and_the_publish_period_changes_while_running(self):
        # (Runs after test_plant_...: unittest orders the tests by name.)
        name = "identifiers/fbdapso: identifier"
        self.assertTrue(self.wait_for(lambda: rospy.has_param("/drive/samples_published")), "plant did not finish")
        self.assertTrue(self.wait_for(lambda: self.counters(name).get("samples used") == "3000", 30),
                        str(self.counters(name)))
        rospy.wait_for_service("/identifiers/fbdapso/reset", 10)
        r = rospy.ServiceProxy("/identifiers/fbdapso/reset", Trigger)()
        self.assertTrue(r.success, r.message)
        self.assertIn("start again", r.message)
        self.assertTrue(self.wait_for(lambda: self.counters(name).get("resets (~reset)") == "1", 10), str(self.counters(name)))
        self.assertEqual(self.counters(name)["monitor and map restarts (time resets, ~reset)"], "1")
        self.assertEqual(self.counters(name)["samples used"], "0")
        self.assertEqual(self.counters(name)["samples received"], "3000")  # the node's totals stay
        set_period = rospy.ServiceProxy("/identifiers/fbdapso/set_publish_period", SetPublishPeriod)
        for bad in (0.0, -1.0, float("nan"), float("inf")):
            r = set_period(bad)
            self.assertFalse(r.success, bad)
            self.assertIn("must be > 0 and finite", r.message)
        self.assertEqual(rospy.get_param("/identifiers/fbdapso/publish_period"), 0.01)
        r = set_period(0.02)
        self.assertTrue(r.success, r.message)
        self.assertEqual(rospy.get_param("/identifiers/fbdapso/publish_period"), 0.02)

    def test_batches_stamped_on_arrival_take_their_times_from_the_index(self):
        # A drive that stamps each batch when it sends it: +-2 periods of jitter on 50-sample batches.
        pub = rospy.Publisher("/jitter_samples", DriveSampleBatch, queue_size=100)
        self.assertTrue(self.wait_for(lambda: pub.get_num_connections() > 0, 20))
        rng = random.Random(7)
        t0, n, period = 7000.0, 50, 1e-4
        for j in range(40):
            pub.publish(self.batch(rospy.Time(t0 + j * n * period + rng.uniform(-2e-4, 2e-4)), j * n))
        # A clock that drifted 30 ms from the drive's (more than half a batch): one step, counted.
        pub.publish(self.batch(rospy.Time(t0 + 40 * n * period + 0.03), 40 * n))
        name = "jitter: identifier"
        self.assertTrue(self.wait_for(lambda: self.counters(name).get("samples received") == "2050", 30),
                        str(self.counters(name)))
        c = self.counters(name)
        self.assertEqual(c["samples skipped (stamp too close)"], "0")
        self.assertEqual(c["time resets (stamps went backwards)"], "0")
        self.assertEqual(c["batch stamps re-anchored (drifted from the index's time)"], "1")
        self.assertEqual(c["time gaps"], "1")  # the 30 ms step only
        self.assertEqual(c["samples used"], "2050")

    def test_no_samples_gives_a_warning(self):
        name = "silent: identifier"
        self.assertTrue(self.wait_for(lambda: name in self.diag and self.diag[name].level == 1, 30))
        self.assertIn("no samples received", self.diag[name].message)


if __name__ == "__main__":
    rostest.rosrun("pmsm_param_id", "identifier_node", IdentifierNode)
