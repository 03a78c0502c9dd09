#!/usr/bin/env python3
"""Test node of nodelets.test."""
import subprocess
import unittest

import rosnode
import rospy
import rostest
from ros_wait import wait_for
from rosgraph_msgs.msg import Log

from pmsm_param_id.msg import DriveSampleBatch, ElectricalParameters, ParameterEstimate


class Nodelets(unittest.TestCase):
    def wait_for(self, predicate, timeout):
        return wait_for(predicate, timeout)

    def test_plant_and_identifiers_in_one_manager_lose_nothing_and_converge(self):
        estimates = {"fbdapso": [], "rls": []}
        truth, log = [], []
        for m in estimates:
            rospy.Subscriber("/identifiers/%s/estimate" % m, ParameterEstimate, estimates[m].append)
        rospy.Subscriber("/drive/true_parameters", ElectricalParameters, truth.append)
        rospy.Subscriber("/rosout", Log, log.append)
        second = []
        rospy.Subscriber("/identifier2/estimate", ParameterEstimate, second.append)
        # The plant waits for this subscriber too (wait_for_subscribers 2), so the run cannot end before
        # this node listens: on a loaded machine it started late and missed the last estimates.
        rospy.Subscriber("/drive/samples_batch", DriveSampleBatch, lambda m: None)
        self.assertTrue(self.wait_for(lambda: rospy.has_param("/drive/samples_published"), 60), "plant did not finish")
        published = rospy.get_param("/drive/samples_published")
        self.assertEqual(published, 3000)
        for m, e in estimates.items():
            self.assertTrue(self.wait_for(lambda: e and e[-1].samples_used == published, 30),
                            "%s did not process every sample" % m)
            last, t = e[-1], truth[-1]
            for name in ("L_q", "psi_f"):
                self.assertLess(abs(getattr(last, name) / getattr(t, name) - 1.0), 0.01, (m, name))
        # The second plant, in real time, paced by the same thread: each of its samples once.
        self.assertTrue(self.wait_for(lambda: rospy.has_param("/drive2/samples_published"), 60), "drive2 did not finish")
        self.assertEqual(rospy.get_param("/drive2/samples_published"), 3000)
        self.assertTrue(self.wait_for(lambda: second and second[-1].samples_used == 3000, 30),
                        "identifier2 did not process every sample of drive2: %s" %
                        (second[-1].samples_used if second else "no estimate"))
        rospy.sleep(0.3)
        self.assertEqual(second[-1].samples_used, 3000, "identifier2 received samples twice")
        # A nodelet with a bad parameter: one FATAL line from the manager, which keeps running.
        loader = subprocess.Popen(["rosrun", "nodelet", "nodelet", "load", "pmsm_param_id/Identifier", "/manager",
                                   "__name:=broken", "_method:=no_such_method"],
                                  stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        try:
            self.assertTrue(self.wait_for(lambda: any("unknown method 'no_such_method'" in entry.msg and
                                                      "does nothing" in entry.msg for entry in log), 30),
                            "the broken nodelet did not say why")
        finally:
            loader.terminate()
            loader.wait(timeout=20)
        self.assertIn("/manager", rosnode.get_node_names())


if __name__ == "__main__":
    rospy.init_node("nodelets_check")
    rostest.rosrun("pmsm_param_id", "nodelets", Nodelets)
