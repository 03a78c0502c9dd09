#!/usr/bin/env python3
"""The rviz plot markers carry the right values (no display needed)."""
import math
import os
import sys
import unittest

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "..", "scripts"))
import estimate_plotter as plotter  # noqa: E402
from visualization_msgs.msg import Marker  # noqa: E402


class Markers(unittest.TestCase):
    def setUp(self):
        self.state = plotter.PlotState(window=0.5, methods=["fbdapso", "ekf"])
        truth = (2.875, 0.0045, 0.0135, 0.17858)
        for k in range(1000):
            t = k * 1e-3
            self.state.add_truth(t, truth)
            self.state.add_estimate("fbdapso", t, (2.875 * (1 + 0.1 / (1 + k)), 0.0045, 0.0135, 0.17858),
                                    (True, k > 100, True, True), 1e-2 / (1 + k))
            self.state.add_estimate("ekf", t, (2.8, 0.0046, 0.0134, 0.18), (True, False, True, True), 0.05,
                                    ["identified", "not_excited", "identified", "identified"])
        self.arr, self.layout = plotter.build_markers(self.state)
        self.by_ns = {}
        for m in self.arr.markers:
            self.by_ns.setdefault(m.ns, []).append(m)

    def test_last_point_is_the_last_estimate(self):
        t0, t1, y0, y1 = self.layout["R_s"]
        ox, oy = plotter.ORIGINS["R_s"]
        strip = self.by_ns["R_s/fbdapso"][0]
        self.assertEqual(strip.type, Marker.LINE_STRIP)
        last_value = 2.875 * (1 + 0.1 / 1000)
        self.assertAlmostEqual(strip.points[-1].x, ox + plotter.PANEL_W, places=9)  # at the right edge: newest
        self.assertAlmostEqual(strip.points[-1].y, oy + (last_value - y0) / (y1 - y0) * plotter.PANEL_H, places=9)

    def test_axes_span_the_data_window(self):
        t0, t1, y0, y1 = self.layout["L_q"]
        self.assertAlmostEqual(t1, 0.999)
        self.assertAlmostEqual(t1 - t0, 0.5)
        self.assertLess(y0, 0.0134)
        self.assertGreater(y1, 0.0135)
        labels = [m.text for m in self.by_ns["L_q/ticklabels"]]
        self.assertIn("%.2f" % t0, labels)  # time axis from t1 - window ...
        self.assertIn("%.2f" % t1, labels)  # ... to the newest stamp

    def test_not_identified_points_and_labels_are_grey_with_their_status(self):
        strip = self.by_ns["L_d/ekf"][0]
        self.assertTrue(all(abs(c.r - plotter.GREY[0]) < 1e-6 for c in strip.colors))
        legend = [m.text for m in self.by_ns["L_d/legend"]]
        self.assertTrue(any(l.startswith("ekf") and l.endswith("not_excited") for l in legend), legend)
        fb = self.by_ns["L_d/fbdapso"][0]
        self.assertAlmostEqual(fb.colors[-1].r, plotter.COLORS["fbdapso"][0])

    def test_long_series_are_thinned_but_keep_the_newest_point(self):
        strip = self.by_ns["R_s/fbdapso"][0]
        self.assertLessEqual(len(strip.points), plotter.MAX_POINTS)
        self.assertEqual(len(strip.points), len(strip.colors))
        self.assertEqual(plotter.thin(list(range(1000)), 250)[-1], 999)
        self.assertLessEqual(len(plotter.thin(list(range(1000)), 250)), 250)

    def test_legend_carries_value_and_error(self):
        legend = [m.text for m in self.by_ns["psi_f/legend"]]
        self.assertIn("ekf 0.18 (+0.80 %)", legend)

    def test_fitness_panel_is_log_scaled(self):
        t0, t1, y0, y1 = self.layout["fitness"]
        logs = [math.log10(f) for _, _, _, f in self.state.series["fbdapso"]]
        self.assertLessEqual(y0, min(logs))  # decades around the data in the window
        self.assertGreaterEqual(y1, max(logs))
        self.assertLess(y1 - y0, 3)
        labels = [m.text for m in self.by_ns["fitness/ticklabels"] if "." in m.text and len(m.text) < 8]
        self.assertEqual(len(set(labels)), len(labels), labels)  # one label per decade, no repeats
        self.assertNotIn("fitness/ekf", self.by_ns)

    def test_stamps_going_back_start_a_new_plot(self):
        self.state.add_estimate("fbdapso", 0.0, (1, 1, 1, 1), (True,) * 4, 1.0)
        self.assertEqual(len(self.state.series["fbdapso"]), 1)


class Monitoring(unittest.TestCase):
    """Temperatures and alarms beside the fitness panel."""

    def build(self, state):
        arr, layout = plotter.build_markers(state)
        by_ns = {}
        for m in arr.markers:
            by_ns.setdefault(m.ns, []).append(m)
        return by_ns, layout

    def test_temperatures_against_truth_and_an_active_alarm(self):
        state = plotter.PlotState(window=1.0, methods=["fbdapso", "rls"])
        nan = float("nan")
        for k in range(200):
            t = k * 1e-2
            state.add_truth(t, (2.875, 0.0045, 0.0135, 0.17858), (40.0 + 0.1 * k, 30.0))
            # the magnet temperature is unknown for the first half (psi_f not identified)
            state.add_estimate("fbdapso", t, (2.875, 0.0045, 0.0135, 0.17858), (True,) * 4, 1e-3, None,
                               (40.5 + 0.1 * k, 31.0 if k >= 100 else nan))
        by_ns, layout = self.build(state)
        t0, t1, y0, y1 = layout["temperature"]
        self.assertLess(y0, 30.0)
        self.assertGreater(y1, 40.0 + 19.9 + 0.5)
        ox, oy = plotter.ORIGINS["temperature"]
        winding = by_ns["temperature/fbdapso/winding"][0]
        self.assertAlmostEqual(winding.points[-1].y, oy + (40.5 + 19.9 - y0) / (y1 - y0) * plotter.PANEL_H, places=9)
        magnet = by_ns["temperature/fbdapso/magnet"][0]
        self.assertLess(len(magnet.points), len(winding.points))  # no point where it was unknown
        legend = [m.text for m in by_ns["temperature/legend"]]
        self.assertIn("fbdapso winding 60.4, magnet 31.0 degC", legend)
        self.assertIn("truth winding 59.9, magnet 30.0 degC", legend)
        self.assertEqual([m.text for m in by_ns["alarms"]], ["no alarm active"])

        state.add_event(1.5, "fbdapso", "demagnetisation", True, "psi_f fell by 5.0 % within 0.3 s")
        by_ns, _ = self.build(state)
        alarm = by_ns["alarms"][0]
        self.assertEqual(alarm.text, "ALARM fbdapso demagnetisation at 1.50 s: psi_f fell by 5.0 % within 0.3 s")
        self.assertEqual((alarm.color.r, alarm.color.g), plotter.ALARM_RED[:2])
        state.add_event(1.9, "fbdapso", "demagnetisation", False, "psi_f consistent with heat")
        by_ns, _ = self.build(state)
        self.assertEqual([m.text for m in by_ns["alarms"]], ["no alarm active"])
        self.assertEqual([m.text for m in by_ns["alarm_log"]],  # the timeline, newest first
                         ["1.90 s fbdapso demagnetisation cleared", "1.50 s fbdapso demagnetisation raised"])

    def test_no_temperature_panel_without_temperatures(self):
        state = plotter.PlotState(window=1.0, methods=["fbdapso"])
        state.add_estimate("fbdapso", 0.0, (1, 1, 1, 1), (True,) * 4, 1.0)
        by_ns, layout = self.build(state)
        self.assertNotIn("temperature", layout)
        self.assertIn("alarms", by_ns)


if __name__ == "__main__":
    unittest.main()
