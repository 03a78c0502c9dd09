#!/usr/bin/env python3
"""Test node of multi_machine.test."""
import unittest
from urllib.parse import urlparse

import rosgraph
import rospy
import rostest
from ros_wait import wait_for

from pmsm_param_id.msg import ElectricalParameters, ParameterEstimate


class MultiMachine(unittest.TestCase):
    def wait_for(self, predicate, timeout):
        return wait_for(predicate, timeout)

    def test_each_node_advertises_its_machine_and_every_sample_crosses(self):
        estimates, truth = [], []
        rospy.Subscriber("/motor_0/identifiers/fbdapso/estimate", ParameterEstimate, estimates.append)
        rospy.Subscriber("/motor_0/drive/true_parameters", ElectricalParameters, truth.append)
        master = rosgraph.Master("/multi_machine_check")
        hosts = {}
        for node in ("/motor_0/drive", "/motor_0/identifiers/fbdapso"):
            self.assertTrue(self.wait_for(lambda: self.lookup(master, node), 30), node)
            hosts[node] = urlparse(self.lookup(master, node)).hostname
        self.assertEqual(hosts["/motor_0/drive"], "127.0.0.2")
        self.assertEqual(hosts["/motor_0/identifiers/fbdapso"], "127.0.0.1")
        self.assertTrue(self.wait_for(lambda: rospy.has_param("/motor_0/drive/samples_published"), 60))
        published = rospy.get_param("/motor_0/drive/samples_published")
        self.assertEqual(published, 3000)
        self.assertTrue(self.wait_for(lambda: estimates and estimates[-1].samples_used == published, 30),
                        "the identifier did not get every sample")
        for name in ("L_q", "psi_f"):
            self.assertLess(abs(getattr(estimates[-1], name) / getattr(truth[-1], name) - 1.0), 0.01, name)

    @staticmethod
    def lookup(master, node):
        try:
            return master.lookupNode(node)
        except rosgraph.MasterError:
            return None


if __name__ == "__main__":
    rospy.init_node("multi_machine_check")
    rostest.rosrun("pmsm_param_id", "multi_machine", MultiMachine)
