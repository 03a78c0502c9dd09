#!/usr/bin/env python3
"""End-to-end tests of the ROS layer: demo.launch -> bag -> replay.launch, bag_tool, pmsm_tool.

Each run starts its own roslaunch on a private master port, so the live bag is always made by
the code under test (no stored fixture to go stale).
"""
import json
import math
import csv as csv_module
import os
import re
import signal
import subprocess
import tempfile
import unittest

import rosbag

PKG = "pmsm_param_id"
METHODS = ["fbdapso", "sapso", "pso", "ekf", "rls"]
PORT = 21000 + os.getpid() % 5000
DEVEL_LIB = os.path.join(os.environ["CMAKE_PREFIX_PATH"].split(":")[0], "lib", PKG)
ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..")


def env():
    e = dict(os.environ)
    e["ROS_MASTER_URI"] = "http://localhost:%d" % PORT
    return e


def roslaunch(launch_file, *args, timeout=180):
    cmd = ["roslaunch", "-p", str(PORT), PKG, launch_file] + list(args)
    r = subprocess.run(cmd, env=env(), timeout=timeout, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    return r.stdout


def tool(name, *args):
    return subprocess.run([os.path.join(DEVEL_LIB, name)] + list(args), stdout=subprocess.PIPE,
                          stderr=subprocess.PIPE, text=True, timeout=300)


def estimates(bag_path):
    """{method: [(stamp_ns, (R_s, L_d, L_q, psi_f), message)]} in bag order."""
    out = {m: [] for m in METHODS}
    with rosbag.Bag(bag_path) as bag:
        for topic, msg, _ in bag.read_messages():
            if topic.endswith("/estimate"):
                out[msg.method].append((msg.header.stamp.to_nsec(), (msg.R_s, msg.L_d, msg.L_q, msg.psi_f), msg))
    return out


def truth(bag_path):
    with rosbag.Bag(bag_path) as bag:
        last = None
        for _, msg, _ in bag.read_messages(topics=["/drive/true_parameters"]):
            last = msg
    return (last.R_s, last.L_d, last.L_q, last.psi_f)


class Pipeline(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.mkdtemp(prefix="pmsm_pipeline_")
        cls.live = os.path.join(cls.tmp, "live.bag")
        cls.replayed = os.path.join(cls.tmp, "replayed.bag")
        cls.live_log = roslaunch("demo.launch", "duration:=0.5", "bag:=" + cls.live)
        # Half speed: on a loaded 2-core machine five identifiers at full speed can still be draining
        # their queues when the launch ends 2 s after the bag (measured: 466 of 495 estimates).
        cls.replay_log = roslaunch("replay.launch", "bag:=" + cls.live, "out_bag:=" + cls.replayed, "rate:=0.5")

    def test_bag_holds_every_sample_at_10khz(self):
        n, expected_index, period, prev_stamp, prev_len = 0, 0, None, None, 0
        with rosbag.Bag(self.live) as bag:
            for _, msg, _ in bag.read_messages(topics=["/drive/samples_batch"]):
                self.assertEqual(msg.first_index, expected_index, "no sample lost")
                if prev_stamp is not None:  # stamps continue without a gap (integer ns: to_sec() is too coarse)
                    self.assertLessEqual(abs(msg.header.stamp.to_nsec() - prev_stamp - round(prev_len * msg.sample_period * 1e9)), 1)
                prev_stamp, prev_len = msg.header.stamp.to_nsec(), len(msg.u_d)
                expected_index += len(msg.u_d)
                n += len(msg.u_d)
                period = msg.sample_period
        self.assertEqual(period, 1e-4)
        self.assertEqual(n, 5000, self.live_log[-2000:])

    def test_every_identifier_processed_every_published_sample(self):
        est = estimates(self.live)
        for m in METHODS:
            self.assertTrue(est[m], "no estimates from " + m)
            self.assertEqual(est[m][-1][2].samples_used, 5000, m)
            self.assertEqual(est[m][-1][2].samples_skipped, 0, m)

    def test_live_fbdapso_converges(self):
        final = estimates(self.live)["fbdapso"][-1][1]
        for value, true in zip(final, truth(self.live)):
            self.assertLess(abs(value - true) / true, 0.01)

    def test_replay_equals_live(self):
        live, replayed = estimates(self.live), estimates(self.replayed)
        for m in METHODS:
            a = {stamp: values for stamp, values, _ in live[m]}
            b = {stamp: values for stamp, values, _ in replayed[m]}
            common = set(a) & set(b)
            self.assertGreaterEqual(len(common), 0.99 * len(a), "%s: %d live, %d replayed, %d common\n%s" % (
                m, len(a), len(b), len(common), self.replay_log[-3000:]))
            for stamp in common:
                self.assertEqual(a[stamp], b[stamp], "%s at %d ns" % (m, stamp))

    def test_live_estimate_equals_core_tool_on_the_same_samples(self):
        csv = os.path.join(self.tmp, "live.csv")
        r = tool("bag_tool", "bag2csv", self.live, csv)
        self.assertEqual(r.returncode, 0, r.stderr)
        out = os.path.join(self.tmp, "core.json")
        r = tool("pmsm_tool", "identify", "--csv", csv, "--method", "fbdapso", "--seed", "1", "--json", out)
        self.assertEqual(r.returncode, 0, r.stderr)
        with open(out) as f:
            core = json.load(f)
        live = estimates(self.live)["fbdapso"][-1][1]
        self.assertEqual(core["samples"], 5000)
        for name, value in zip(["R_s", "L_d", "L_q", "psi_f"], live):
            self.assertEqual(core[name], value, name)


class Report(unittest.TestCase):
    """The report tool on bags from demo.launch (Pipeline's live bag is made again here, short)."""

    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.mkdtemp(prefix="pmsm_report_")
        cls.bag = os.path.join(cls.tmp, "live.bag")
        cls.log = roslaunch("demo.launch", "duration:=0.3", "bag:=" + cls.bag)

    def report(self, bag, out):
        script = os.path.join(os.path.dirname(__file__), "..", "..", "scripts", "report.py")
        return subprocess.run(["/usr/bin/python3", script, bag, "--out", out], stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True, timeout=300)

    def test_figures_and_table_hold_the_bag_estimates(self):
        out = os.path.join(self.tmp, "report")
        r = self.report(self.bag, out)
        self.assertEqual(r.returncode, 0, r.stderr)
        for name in ("R_s.png", "L_d.png", "L_q.png", "psi_f.png", "fitness.png", "report.md"):
            self.assertGreater(os.path.getsize(os.path.join(out, name)), 1000, name)
        with open(os.path.join(out, "report.md")) as f:
            table = f.read()
        rows = {line.split("|")[1].strip().split(" ")[0]: [c.strip() for c in line.split("|")[2:-1]]
                for line in table.splitlines() if line.startswith("| ") and "[" in line.split("|")[1]}
        header = [l for l in table.splitlines() if l.startswith("| Parameter")][0]
        columns = [c.strip() for c in header.split("|")[1:-1]]
        est = estimates(self.bag)
        for i, p in enumerate(["R_s", "L_d", "L_q", "psi_f"]):
            for m in METHODS:
                cell = rows[p][columns.index(m) - 1]
                self.assertAlmostEqual(float(cell.split(" ")[0]), est[m][-1][1][i], delta=abs(est[m][-1][1][i]) * 1e-5,
                                       msg="%s %s: %s" % (m, p, cell))
        self.assertIn("paper fbdapso", header)  # wc1_drive is recognised as the paper's wc1

    def test_a_fleet_bag_is_read_by_type_and_one_drive_chosen_by_namespace(self):
        # The demo bag's messages under a fleet's namespaces: found by type, not by /drive/ names.
        one, two = os.path.join(self.tmp, "motor3.bag"), os.path.join(self.tmp, "motors34.bag")
        with rosbag.Bag(self.bag) as src, rosbag.Bag(one, "w") as a, rosbag.Bag(two, "w") as b:
            for topic, msg, t in src.read_messages():
                a.write("/motor_3" + topic, msg, t)
                b.write("/motor_3" + topic, msg, t)
                b.write("/motor_4" + topic, msg, t)
        r = self.report(one, os.path.join(self.tmp, "report_motor3"))
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertNotIn("no true parameters", r.stderr)
        with open(os.path.join(self.tmp, "report_motor3", "report.md")) as f:
            self.assertIn("| Parameter", f.read())
        r = self.report(two, os.path.join(self.tmp, "report_motors34"))
        self.assertEqual(r.returncode, 2, r.stderr)
        self.assertIn("several drives in this bag", r.stderr)
        script = os.path.join(os.path.dirname(__file__), "..", "..", "scripts", "report.py")
        r = subprocess.run(["/usr/bin/python3", script, two, "--out", os.path.join(self.tmp, "report_motor4"),
                            "--namespace", "/motor_4"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                           timeout=300)
        self.assertEqual(r.returncode, 0, r.stderr)

    def test_a_bag_without_estimates_or_truth_says_what_is_missing(self):
        tmp = tempfile.mkdtemp(prefix="pmsm_report_missing_")
        csv, bag = os.path.join(tmp, "x.csv"), os.path.join(tmp, "x.bag")
        with open(csv, "w") as f:
            f.write("t,u_d,u_q,i_d,i_q,omega_e\n")
            for k in range(20):
                f.write("%g,1,2,3,4,5\n" % (k * 1e-4))
        self.assertEqual(tool("bag_tool", "csv2bag", csv, bag).returncode, 0)
        r = self.report(bag, os.path.join(tmp, "report"))
        self.assertEqual(r.returncode, 2, r.stderr)  # what exists is drawn, but a report needs estimates
        self.assertIn("no ParameterEstimate messages: nothing was identified", r.stderr)
        self.assertIn("no estimates", r.stderr)
        self.assertIn("no true parameters", r.stderr)
        with open(os.path.join(tmp, "report", "report.md")) as f:
            self.assertIn("Missing from this bag", f.read())
        self.assertTrue(os.path.exists(os.path.join(tmp, "report", "R_s.png")))

    def test_not_a_bag_is_one_clear_line(self):
        path = os.path.join(self.tmp, "notes.bag")
        with open(path, "w") as f:
            f.write("this is not a bag\n")
        r = self.report(path, os.path.join(self.tmp, "nothing"))
        self.assertEqual(r.returncode, 2, r.stderr)
        self.assertEqual(len(r.stderr.strip().splitlines()), 1, r.stderr)
        self.assertIn("not a readable bag", r.stderr)

    def test_an_out_folder_that_cannot_be_made_and_a_bad_condition_exit_2(self):
        r = self.report(self.bag, "/proc/pmsm_report_here")
        self.assertEqual(r.returncode, 2, r.stderr)
        self.assertEqual(len(r.stderr.strip().splitlines()), 1, r.stderr)
        self.assertIn("error: --out: cannot create '/proc/pmsm_report_here'", r.stderr)
        script = os.path.join(os.path.dirname(__file__), "..", "..", "scripts", "report.py")
        r = subprocess.run(["/usr/bin/python3", script, self.bag, "--condition", "xyz"], stdout=subprocess.PIPE,
                           stderr=subprocess.PIPE, text=True, timeout=60)
        self.assertEqual(r.returncode, 2, r.stderr)
        self.assertIn("invalid choice: 'xyz'", r.stderr)


class Tools(unittest.TestCase):
    def test_identify_reports_bad_rows_by_line_and_keeps_the_rest(self):
        tmp = tempfile.mkdtemp(prefix="pmsm_identify_")
        csv = os.path.join(tmp, "log.csv")
        scenario = os.path.join(os.path.dirname(__file__), "..", "..", "config", "scenarios", "wc1_drive.yaml")
        self.assertEqual(tool("pmsm_tool", "simulate", "--scenario", scenario, "--csv", csv, "--duration", "0.2").returncode, 0)
        with open(csv) as f:
            lines = f.read().splitlines()
        cells = lines[101].split(",")
        cells[4] = "nan"                     # line 102: a non-finite current
        lines[101] = ",".join(cells)
        lines.insert(1500, lines[1200])      # line 1501: time goes back (the log restarts)
        with open(csv, "w") as f:
            f.write("\n".join(lines) + "\n")
        out = os.path.join(tmp, "e.json")
        r = tool("pmsm_tool", "identify", "--csv", csv, "--method", "fbdapso", "--json", out)
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertIn(csv + ":102: skipped: non-finite value", r.stderr)
        self.assertIn(csv + ":1501: time went backwards: identifier reset", r.stderr)
        with open(out) as f:
            e = json.load(f)
        self.assertEqual(e["skipped"], 1)
        self.assertEqual(e["time_resets"], 1)
        self.assertEqual(e["samples"], 2000)  # 2001 rows, one skipped

    def test_identify_traces_the_estimate_along_the_log(self):
        tmp = tempfile.mkdtemp(prefix="pmsm_trace_")
        scenario = os.path.join(ROOT, "config", "scenarios", "wc1_drive.yaml")
        csv, trace, out = (os.path.join(tmp, n) for n in ("log.csv", "trace.csv", "e.json"))
        self.assertEqual(tool("pmsm_tool", "simulate", "--scenario", scenario, "--csv", csv, "--duration", "0.4").returncode, 0)
        r = tool("pmsm_tool", "identify", "--csv", csv, "--method", "wls", "--trace", trace, "--json", out)
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertIn("estimates along the log written to " + trace, r.stdout)
        with open(trace) as f:
            rows = list(csv_module.DictReader(f))
        with open(out) as f:
            final = json.load(f)
        times = [float(row["t"]) for row in rows]
        # One row every 10 ms of log time from the first fitness block on, to the log's end.
        self.assertGreater(len(rows), 30)
        self.assertTrue(all(0.0099 < b - a < 0.0102 for a, b in zip(times, times[1:])), times[:5])
        self.assertGreater(times[-1], final["t"] - 0.0101)
        last = rows[-1]
        for name in ("R_s", "L_d", "L_q", "psi_f"):
            self.assertIn(last[name + "_status"], ("identified", "not_excited", "poor_fit", "no_data"))
            # 10 ms before the end the exact fit already holds the final values.
            self.assertAlmostEqual(float(last[name]) / final[name], 1.0, delta=2e-3, msg=name)
        self.assertEqual(last["R_s_status"], final["status"]["R_s"])
        self.assertTrue(0 < float(last["L_q_relative_uncertainty"]) < 0.01)
        telemetry = os.path.join(tmp, "slow.csv")
        self.assertEqual(tool("pmsm_tool", "simulate", "--scenario", scenario, "--csv", telemetry, "--duration", "2",
                              "--telemetry-period", "0.02").returncode, 0)
        r = tool("pmsm_tool", "identify", "--csv", telemetry, "--trace", trace)
        self.assertEqual(r.returncode, 2)
        self.assertIn("--trace need the current loop's samples; this log is telemetry", r.stderr)

    def test_too_few_samples_for_the_horizon_is_a_clear_error(self):
        tmp = tempfile.mkdtemp(prefix="pmsm_identify_")
        csv = os.path.join(tmp, "short.csv")
        with open(csv, "w") as f:
            f.write("t,u_d,u_q,i_d,i_q,omega_e\n" + "".join("%g,1,2,3,4,5\n" % (k * 1e-4) for k in range(10)))
        r = tool("pmsm_tool", "identify", "--csv", csv, "--method", "rls")
        self.assertEqual(r.returncode, 2)
        self.assertIn("only 10 usable samples: fewer than one fitness block", r.stderr)

    def test_an_interrupted_bench_reports_the_seeds_it_finished(self):
        p = subprocess.Popen([os.path.join(DEVEL_LIB, "pmsm_tool"), "bench", "--scenario",
                              os.path.join(ROOT, "config/scenarios/wc1.yaml"), "--reference",
                              os.path.join(ROOT, "config/reference/paper_tables.csv"), "--seeds", "200",
                              "--methods", "rls", "--threads", "1"],
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        first = p.stderr.readline()  # the first progress line: a seed or more finished
        self.assertRegex(first, r"\[bench wc1\] \d+ of 200 seeds done, about \d+ s left")
        p.send_signal(signal.SIGINT)
        out, err = p.communicate(timeout=120)
        self.assertEqual(p.returncode, 130, err)
        self.assertRegex(err, r"interrupted: \d+ of 200 seeds finished")
        finished = int(re.search(r"interrupted: (\d+) of 200", err).group(1))
        self.assertIn("Scenario wc1: %d seeds" % finished, out)

    def test_command_line_errors_exit_2_and_help_exits_0(self):
        for args, text in ((["identify"], "--csv is required"), (["identify", "--csv", "x.csv", "--bogus"], "--bogus"),
                           (["bench", "--scenario", "s.yaml", "--reference", "r.csv", "--seeds", "many"], "--seeds"),
                           ([], "A subcommand is required"),
                           (["simulate", "--scenario", "s.yaml", "--csv", "o.csv", "--seed", "-5"], "--seed"),
                           (["bench", "--scenario", os.path.join(ROOT, "config/scenarios/wc1.yaml"), "--reference",
                             "/nonexistent/paper.csv", "--seeds", "1"], "--reference: cannot read")):
            r = tool("pmsm_tool", *args)
            self.assertEqual(r.returncode, 2, (args, r.stderr))
            self.assertIn(text, r.stderr)
            self.assertEqual(len([l for l in r.stderr.splitlines() if l.startswith("error:")]), 1, r.stderr)
        r = tool("pmsm_tool", "identify", "--help")
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertIn("--csv", r.stdout)


class BadParameters(unittest.TestCase):
    def test_unknown_method_stops_the_node_with_one_line_naming_the_parameter(self):
        master = subprocess.Popen(["rosmaster", "--core", "-p", str(PORT + 1)], stdout=subprocess.DEVNULL,
                                  stderr=subprocess.DEVNULL)
        try:
            e = env()
            e["ROS_MASTER_URI"] = "http://localhost:%d" % (PORT + 1)
            r = subprocess.run([os.path.join(DEVEL_LIB, "identifier"), "_method:=bogus"], env=e, timeout=30,
                               stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
            self.assertEqual(r.returncode, 1, r.stdout)
            lines = [l for l in r.stdout.splitlines() if "FATAL" in l]
            self.assertEqual(len(lines), 1, r.stdout)
            self.assertIn("parameter ~method: unknown method 'bogus' (expected fbdapso, sapso, pso, ekf, rls, wls)", lines[0])
            r = subprocess.run([os.path.join(DEVEL_LIB, "identifier"), "_method:=pso", "_publish_period:=-1"], env=e,
                               timeout=30, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
            self.assertEqual(r.returncode, 1, r.stdout)
            self.assertIn("parameter ~publish_period: must be > 0", r.stdout)
            for arg, message in (("_seed:=abc", "parameter ~seed: expected an integer, got the text 'abc'"),
                                 ("_method:=7", "parameter ~method: expected a text, got the integer 7")):
                r = subprocess.run([os.path.join(DEVEL_LIB, "identifier"), arg], env=e, timeout=30,
                                   stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
                self.assertEqual(r.returncode, 1, r.stdout)
                lines = [l for l in r.stdout.splitlines() if "FATAL" in l]
                self.assertEqual(len(lines), 1, r.stdout)
                self.assertIn(message, lines[0])
            # (private parameters stay on this master: each run sets again what an earlier one spoiled)
            for args, message in ((["_map_publish_period:=0"], "parameter ~map_publish_period: must be > 0"),
                                  (["_map_publish_period:=1", "_map_csv:=3"],
                                   "parameter ~map_csv: expected a text, got the integer 3")):
                r = subprocess.run([os.path.join(DEVEL_LIB, "identifier"), "_method:=pso", "_seed:=1",
                                    "_publish_period:=0.001"] + args, env=e, timeout=30,
                                   stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
                self.assertEqual(r.returncode, 1, r.stdout)
                lines = [l for l in r.stdout.splitlines() if "FATAL" in l]
                self.assertEqual(len(lines), 1, r.stdout)
                self.assertIn(message, lines[0])
        finally:
            master.terminate()
            master.wait()


class BenchAndIdentifyInputs(unittest.TestCase):
    def test_an_empty_method_list_is_refused(self):
        scenario = os.path.join(ROOT, "config", "scenarios", "wc1_drive.yaml")
        reference = os.path.join(ROOT, "config", "reference", "paper_tables.csv")
        r = tool("pmsm_tool", "bench", "--scenario", scenario, "--reference", reference, "--methods", ",,", "--seeds", "1")
        self.assertEqual(r.returncode, 2, r.stdout)
        self.assertEqual(r.stdout, "")
        self.assertIn("--methods: no method named", r.stderr)

    def test_bench_pairs_recognition_times_by_seed(self):
        # The printed paired comparison must be the one the per-seed records give.
        scenario = os.path.join(ROOT, "config", "scenarios", "wc1_drive.yaml")
        reference = os.path.join(ROOT, "config", "reference", "paper_tables.csv")
        out = os.path.join(tempfile.mkdtemp(prefix="pmsm_paired_"), "bench.json")
        r = tool("pmsm_tool", "bench", "--scenario", scenario, "--reference", reference, "--methods",
                 "fbdapso,sapso,pso", "--seeds", "5", "--json", out)
        self.assertEqual(r.returncode, 0, r.stderr)
        with open(out) as f:
            records = json.load(f)
        times = {}
        for rec in records:
            times.setdefault(rec["method"], {})[rec["seed"]] = rec["recognition_time"]
        for other in ("sapso", "pso"):
            pairs = [(times["fbdapso"][s], times[other][s]) for s in sorted(times["fbdapso"])]
            both = [(a, b) for a, b in pairs if a is not None and b is not None]
            self.assertGreaterEqual(len(both), 3, pairs)  # wc1_drive: every swarm recognises
            ratios = sorted(a / b for a, b in both)
            n = len(ratios)
            med = ratios[n // 2] if n % 2 else 0.5 * (ratios[n // 2 - 1] + ratios[n // 2])
            line = "fbdapso/%-6s faster in %d of %d seeds where both recognised" % (
                other, sum(1 for a, b in both if a < b), n)
            self.assertIn(line, r.stdout)
            self.assertIn("ratio median %.2f, quartiles %.2f-%.2f" % (med, ratios[n // 4], ratios[3 * n // 4]), r.stdout)

    def test_a_log_in_rpm_and_milliamps_is_read_with_its_units(self):
        tmp = tempfile.mkdtemp(prefix="pmsm_units_")
        scenario = os.path.join(ROOT, "config", "scenarios", "wc1_drive.yaml")
        csv, other = os.path.join(tmp, "si.csv"), os.path.join(tmp, "other.csv")
        self.assertEqual(tool("pmsm_tool", "simulate", "--scenario", scenario, "--csv", csv, "--duration", "0.3").returncode, 0)
        # Neither file has the angle (with it, omega_e dt would come from the angle in one and not
        # the other: the same data, but a different integral).
        si = os.path.join(tmp, "si_no_angle.csv")
        with open(csv) as f, open(other, "w") as g, open(si, "w") as h:
            rows = list(csv_module.DictReader(f))
            g.write("time_ms,vd,vq,id_mA,iq_mA,speed_rpm\n")
            h.write("t,u_d,u_q,i_d,i_q,omega_e\n")
            for x in rows:
                g.write("%.17g,%s,%s,%.17g,%.17g,%.17g\n" % (float(x["t"]) * 1e3, x["u_d"], x["u_q"], float(x["i_d"]) * 1e3,
                                                           float(x["i_q"]) * 1e3, float(x["omega_e"]) / 4 * 60 / (2 * math.pi)))
                h.write("%s,%s,%s,%s,%s,%s\n" % (x["t"], x["u_d"], x["u_q"], x["i_d"], x["i_q"], x["omega_e"]))
        a, b = os.path.join(tmp, "a.json"), os.path.join(tmp, "b.json")
        self.assertEqual(tool("pmsm_tool", "identify", "--csv", si, "--method", "rls", "--json", a).returncode, 0)
        r = tool("pmsm_tool", "identify", "--csv", other, "--method", "rls", "--json", b, "--column", "t=time_ms",
                 "--column", "u_d=vd", "--column", "u_q=vq", "--column", "i_d=id_mA", "--column", "i_q=iq_mA",
                 "--column", "omega_e=speed_rpm", "--time-unit", "ms", "--current-unit", "mA", "--speed-unit", "rpm",
                 "--pole-pairs", "4")
        self.assertEqual(r.returncode, 0, r.stderr)
        with open(a) as f, open(b) as g:
            ja, jb = json.load(f), json.load(g)
        for p in ("R_s", "L_d", "L_q", "psi_f"):
            self.assertAlmostEqual(ja[p] / jb[p], 1.0, places=6)
            self.assertEqual(jb["status"][p], "identified", jb["reason"][p])
        # Without the units the same file is a poor fit, and the tool says why.
        r = tool("pmsm_tool", "identify", "--csv", other, "--method", "rls", "--json", b, "--column", "t=time_ms",
                 "--column", "u_d=vd", "--column", "u_q=vq", "--column", "i_d=id_mA", "--column", "i_q=iq_mA",
                 "--column", "omega_e=speed_rpm", "--time-unit", "ms", "--current-unit", "mA")
        self.assertEqual(r.returncode, 0, r.stderr)
        with open(b) as g:
            jb = json.load(g)
        self.assertFalse(any(jb["identifiable"].values()), jb["status"])
        self.assertIn("rpm", jb["fit"]["likely_cause"])


class Telemetry(unittest.TestCase):
    def test_a_vesc_log_across_midnight_is_identified_and_an_older_one_names_its_missing_columns(self):
        tmp = tempfile.mkdtemp(prefix="pmsm_vesc_")
        log, out = os.path.join(tmp, "vesc.csv"), os.path.join(tmp, "vesc.json")
        scenario = os.path.join(ROOT, "config", "scenarios", "telemetry_duty_cycle.yaml")
        r = tool("pmsm_tool", "simulate", "--scenario", scenario, "--csv", log, "--duration", "12",
                 "--telemetry-period", "0.02", "--format", "vesc", "--clock-start", "86395")
        self.assertEqual(r.returncode, 0, r.stderr)
        with open(log) as f:
            header = f.readline().strip().split(";")
            clock = [float(line.split(";")[0]) for line in f]
        self.assertEqual(header[:7], ["ms_today", "d_axis_voltage", "q_axis_voltage", "d_axis_current",
                                      "q_axis_current", "erpm", "input_voltage"])
        self.assertLess(min(clock), 1000.0)  # the clock passed midnight
        r = tool("pmsm_tool", "identify", "--csv", log, "--format", "vesc", "--method", "fbdapso", "--json", out)
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertIn("steady-state fit", r.stderr)
        self.assertIn("does not apply to telemetry", r.stderr)
        with open(out) as f:
            j = json.load(f)
        self.assertEqual(j["method"], "steady_state")
        for p in ("L_q", "psi_f"):
            self.assertEqual(j["status"][p], "identified", j["reason"][p])
        self.assertLess(abs(j["psi_f"] / 0.55 - 1.0), 0.01)
        self.assertLess(abs(j["L_q"] / 0.051 - 1.0), 0.01)
        self.assertEqual(j["status"]["L_d"], "not_excited")  # i_d never varies
        # Older firmware logs no d/q voltages: one line naming the column, exit 2.
        old = os.path.join(tmp, "old.csv")
        with open(log) as f, open(old, "w") as g:
            for line in f:
                cells = line.rstrip("\n").split(";")
                g.write(";".join([cells[0]] + cells[3:]) + "\n")
        r = tool("pmsm_tool", "identify", "--csv", old, "--format", "vesc")
        self.assertEqual(r.returncode, 2)
        self.assertIn("missing column 'd_axis_voltage'", r.stderr)


class Thermal(unittest.TestCase):
    def test_a_config_with_only_a_thermal_block_gives_both_temperatures(self):
        tmp = tempfile.mkdtemp(prefix="pmsm_thermal_")
        scenario = os.path.join(ROOT, "config", "scenarios", "wc1_drive.yaml")
        csv, cfg, out = (os.path.join(tmp, n) for n in ("log.csv", "thermal.yaml", "out.json"))
        self.assertEqual(tool("pmsm_tool", "simulate", "--scenario", scenario, "--csv", csv, "--duration", "0.4").returncode, 0)
        with open(cfg, "w") as f:
            f.write("thermal:\n  reference_temperature: 40.0\n  R_s_at_reference: 2.7\n  psi_f_at_reference: 0.18\n")
        r = tool("pmsm_tool", "identify", "--csv", csv, "--config", cfg, "--json", out)
        self.assertEqual(r.returncode, 0, r.stderr)
        with open(out) as f:
            j = json.load(f)
        # R_s = 2.875 is 6.5 % above 2.7: 40 + 0.0648 / 3.93e-3 = 56.5 degC; psi_f 0.17858 is 0.79 % below
        # 0.18: 40 + 0.0079 / 1.2e-3 = 46.6 degC.
        self.assertAlmostEqual(j["winding_temperature"], 40.0 + (2.875 / 2.7 - 1) / 3.93e-3, delta=3.0)
        self.assertAlmostEqual(j["magnet_temperature"], 40.0 + (0.17858 / 0.18 - 1) / -1.2e-3, delta=5.0)


class Monitoring(unittest.TestCase):
    """A live run with a 5 % demagnetisation at 1.5 s: the event reaches the bag and the report."""

    def test_demagnetisation_event_is_recorded_and_reported_with_temperatures(self):
        tmp = tempfile.mkdtemp(prefix="pmsm_monitoring_")
        bag, out = os.path.join(tmp, "demag.bag"), os.path.join(tmp, "report")
        scenario = os.path.join(ROOT, "config", "scenarios", "demagnetisation.yaml")
        config = os.path.join(ROOT, "config", "identifiers", "cold_start.yaml")
        roslaunch("demo.launch", "scenario:=" + scenario, "duration:=2.3", "config:=" + config, "bag:=" + bag)
        origin, raised = None, {}
        with rosbag.Bag(bag) as b:
            for topic, msg, _ in b.read_messages(topics=["/drive/samples_batch"]):
                origin = msg.header.stamp.to_sec() if origin is None else min(origin, msg.header.stamp.to_sec())
            for topic, msg, _ in b.read_messages():
                if topic.endswith("/events") and msg.raised:
                    raised.setdefault(msg.method, []).append((msg.kind, msg.header.stamp.to_sec() - origin))
        for m in METHODS:  # every identifier raised it, 0 to 0.5 s after the step, and nothing else
            self.assertIn(m, raised, "no alarm from %s" % m)
            kinds = [k for k, _ in raised[m]]
            self.assertEqual(kinds, ["demagnetisation"], m)
            self.assertGreaterEqual(raised[m][0][1], 1.5, m)
            self.assertLessEqual(raised[m][0][1], 2.0, m)
        r = subprocess.run(["/usr/bin/python3", os.path.join(ROOT, "scripts", "report.py"), bag, "--out", out],
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, timeout=300)
        self.assertEqual(r.returncode, 0, r.stderr)
        for name in ("alarms.png", "temperatures.png"):
            self.assertGreater(os.path.getsize(os.path.join(out, name)), 1000, name)
        with open(os.path.join(out, "report.md")) as f:
            report = f.read()
        self.assertIn("Temperatures at the end", report)
        alarm_rows = [line for line in report.splitlines() if "| demagnetisation | raised |" in line]
        self.assertEqual(len(alarm_rows), len(METHODS), report)


class MotorMapping(unittest.TestCase):
    """A live run of the saturating machine through three load levels: every identifier's map reaches
    the bag with a cell per level (L_q identified in each), identified within 2 % of the truth of its moment; the CSV it
    wrote drives the simulator (pmsm_tool simulate with a scenario that names it); the report draws it."""

    def test_the_map_of_a_saturating_machine_is_published_written_and_reported(self):
        tmp = tempfile.mkdtemp(prefix="pmsm_map_")
        bag, out, maps = os.path.join(tmp, "map.bag"), os.path.join(tmp, "report"), os.path.join(tmp, "maps")
        os.makedirs(maps)
        scenario = os.path.join(ROOT, "config", "scenarios", "saturated_map.yaml")
        config = os.path.join(ROOT, "config", "identifiers", "saturating_machine.yaml")
        roslaunch("demo.launch", "scenario:=" + scenario, "duration:=3.0", "config:=" + config, "bag:=" + bag,
                  "map_dir:=" + maps)
        last, truth_at = {}, []
        with rosbag.Bag(bag) as b:
            for topic, msg, _ in b.read_messages(topics=["/drive/true_parameters"]):
                truth_at.append((msg.header.stamp.to_sec(), (msg.R_s, msg.L_d, msg.L_q, msg.psi_f)))
            for topic, msg, _ in b.read_messages():
                if topic.endswith("/map"):
                    last[msg.method] = msg
        truth_at.sort()
        stamps = [t for t, _ in truth_at]
        import bisect
        for m in METHODS:
            self.assertIn(m, last, "no map from %s" % m)
            levels, full = set(), set()
            for cell in last[m].cells:
                for i in range(4):
                    if math.isnan(cell.identified[i]):
                        continue
                    t = cell.identified_stamp[i].to_sec()
                    true = truth_at[max(bisect.bisect_right(stamps, t + 1e-9) - 1, 0)][1]
                    self.assertLess(abs(cell.identified[i] / true[i] - 1), 0.02, "%s cell i_q %.2f parameter %d" % (m, cell.i_q, i))
                if not math.isnan(cell.identified[2]):
                    levels.add(round(cell.i_q))
                if not any(math.isnan(cell.identified[i]) for i in (1, 2, 3)):
                    full.add(round(cell.i_q))
            self.assertEqual(levels, {2, 4, 6}, m)  # L_q at every level
            if m in ("fbdapso", "sapso", "pso"):  # L_d and psi_f too at most levels (the EKF and RLS
                self.assertGreaterEqual(len(full), 2, m)  # leave psi_f not identified at most)
            csv_path = os.path.join(maps, m + "_map.csv")
            self.assertTrue(os.path.isfile(csv_path), csv_path)
        # The learnt map drives the simulator: a scenario beside it that names it.
        with open(scenario) as f:
            text = f.read()
        start = text.index("saturation:")
        end = text.index("drive:")
        learnt = os.path.join(maps, "learnt.yaml")
        with open(learnt, "w") as f:
            f.write(text[:start] + "saturation:\n  flux_map_csv: fbdapso_map.csv\n" + text[end:])
        r = tool("pmsm_tool", "simulate", "--scenario", learnt, "--csv", os.path.join(tmp, "learnt.csv"), "--duration", "0.5")
        self.assertEqual(r.returncode, 0, r.stderr)
        r = subprocess.run(["/usr/bin/python3", os.path.join(ROOT, "scripts", "report.py"), bag, "--out", out],
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, timeout=300)
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertGreater(os.path.getsize(os.path.join(out, "map.png")), 1000)
        with open(os.path.join(out, "report.md")) as f:
            report = f.read()
        self.assertIn("Map of the motor", report)
        self.assertIn("[map](map.png)", report)


class Package(unittest.TestCase):
    def test_catkin_lint_finds_nothing_at_its_strictest(self):
        # No rosdep database offline: catkin_lint then checks the build files but not the keys.
        r = subprocess.run(["catkin_lint", "-W2", "--strict", os.path.abspath(ROOT)], stdout=subprocess.PIPE,
                           stderr=subprocess.PIPE, text=True, timeout=120, env=dict(os.environ, ROS_DISTRO="noetic"))
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        self.assertIn("found 0 problems", r.stdout + r.stderr)


class CsvToBag(unittest.TestCase):
    def test_a_drive_log_becomes_a_bag_that_replays_and_converges(self):
        tmp = tempfile.mkdtemp(prefix="pmsm_csv2bag_")
        csv, bag, out = (os.path.join(tmp, n) for n in ("log.csv", "log.bag", "out.bag"))
        scenario = os.path.join(os.path.dirname(__file__), "..", "..", "config", "scenarios", "wc2_drive.yaml")
        self.assertEqual(tool("pmsm_tool", "simulate", "--scenario", scenario, "--csv", csv, "--duration", "0.3").returncode, 0)
        r = tool("bag_tool", "csv2bag", csv, bag)
        self.assertEqual(r.returncode, 0, r.stderr)
        log = roslaunch("replay.launch", "bag:=" + bag, "out_bag:=" + out)
        est = estimates(out)["fbdapso"]
        self.assertTrue(est, log[-3000:])
        self.assertEqual(est[-1][2].samples_used, 3000)
        for value, true in zip(est[-1][1], truth(bag)):
            self.assertLess(abs(value - true) / true, 0.01)

    def test_a_bag_recorded_before_v_dc_is_named_and_upgraded_by_rosbag_fix(self):
        # test/data/drive_samples_0.1.0.bag: 200 robot-joint samples written by bag_tool 0.1.0, when
        # DriveSampleBatch had no v_dc. Read as it is, the tool names the upgrade; rosbag fix with the
        # package's rules makes it readable, every sample kept and v_dc "not logged".
        tmp = tempfile.mkdtemp(prefix="pmsm_migration_")
        old = os.path.join(ROOT, "test", "data", "drive_samples_0.1.0.bag")
        rules = os.path.join(ROOT, "migration_rules", "drive_samples.bmr")
        fixed, csv = os.path.join(tmp, "fixed.bag"), os.path.join(tmp, "fixed.csv")
        r = tool("bag_tool", "bag2csv", old, csv)
        self.assertEqual(r.returncode, 2, r.stdout + r.stderr)
        self.assertIn("older definition (before v_dc)", r.stderr)
        self.assertIn("rosbag fix", r.stderr)
        r = subprocess.run(["rosbag", "fix", old, fixed, rules], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                           text=True, timeout=120)
        self.assertEqual(r.returncode, 0, r.stdout)
        r = tool("bag_tool", "bag2csv", fixed, csv)
        self.assertEqual(r.returncode, 0, r.stderr)
        with open(csv) as f:
            rows = list(csv_module.DictReader(f))
        self.assertEqual(len(rows), 200)
        self.assertTrue(all(math.isnan(float(row["v_dc"])) for row in rows))
        self.assertTrue(all(math.isfinite(float(row["theta_e"])) for row in rows))
        with rosbag.Bag(old) as bag_old, rosbag.Bag(fixed) as bag_new:
            before = [m for _, m, _ in bag_old.read_messages(topics=["/drive/samples_batch"], raw=True)]
            after = [m for _, m, _ in bag_new.read_messages(topics=["/drive/samples_batch"])]
        self.assertEqual(len(before), len(after))
        self.assertEqual(sum(len(m.i_q) for m in after), 200)
        self.assertTrue(all(len(m.v_dc) == 0 for m in after))

    def test_time_columns_that_restart_are_in_ns_or_unix_epoch(self):
        tmp = tempfile.mkdtemp(prefix="pmsm_csv2bag_")
        header = "t,u_d,u_q,i_d,i_q,omega_e\n"
        row = lambda t, k: "%s,%g,100,%g,9,418.9\n" % (t, -50 + math.sin(k), 0.1 * math.cos(k))
        # Unix-epoch seconds at 10 kHz: the column resolves 0.24 us; batches stay whole and the period exact.
        epoch, epoch_bag = os.path.join(tmp, "epoch.csv"), os.path.join(tmp, "epoch.bag")
        with open(epoch, "w") as f:
            f.write(header + "".join(row("%.6f" % (1.7e9 + k * 1e-4), k) for k in range(20000)))
        r = tool("bag_tool", "csv2bag", epoch, epoch_bag)
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertIn("wrote 20000 samples in 200 messages (T_s = 0.0001 s)", r.stdout)
        # A time column in ns: one line naming the unit, exit 2, no half-written bag.
        ns, ns_bag = os.path.join(tmp, "ns.csv"), os.path.join(tmp, "ns.bag")
        with open(ns, "w") as f:
            f.write(header + "".join(row("%d" % (1700000000000000000 + k * 100000), k) for k in range(100)))
        r = tool("bag_tool", "csv2bag", ns, ns_bag)
        self.assertEqual(r.returncode, 2, r.stderr)
        self.assertIn("is the time column in ns or us?", r.stderr)
        self.assertEqual([n for n in os.listdir(tmp) if n.startswith("ns.bag")], [])
        # A log whose time restarts once: its stretches play one after the other, the stamps go back once.
        back, back_bag = os.path.join(tmp, "back.csv"), os.path.join(tmp, "back.bag")
        with open(back, "w") as f:
            f.write(header + "".join(row("%.4f" % (k * 1e-4), k) for _ in range(2) for k in range(3000)))
        r = tool("bag_tool", "csv2bag", back, back_bag)
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertIn("back.csv:3002: time goes back from 0.2999 to 0 s", r.stderr)
        with rosbag.Bag(back_bag) as bag:
            batches = [(t.to_nsec(), m.header.stamp.to_nsec(), m.first_index)
                       for _, m, t in bag.read_messages(topics=["/drive/samples_batch"])]
        self.assertEqual(len(batches), 60)
        self.assertEqual([b[0] for b in batches], sorted(b[0] for b in batches))  # played in the log's order
        backs = [k for k in range(1, len(batches)) if batches[k][1] < batches[k - 1][1]]
        self.assertEqual(backs, [30])
        self.assertEqual(batches[30][2], 0)  # the restarted stretch counts from 0

    def test_not_a_csv_is_one_clear_line(self):
        tmp = tempfile.mkdtemp(prefix="pmsm_csv2bag_")
        bad = os.path.join(tmp, "bad.csv")
        with open(bad, "w") as f:
            f.write("time,volts\n1,2\n")
        r = tool("bag_tool", "csv2bag", bad, os.path.join(tmp, "x.bag"))
        self.assertEqual(r.returncode, 2)
        self.assertEqual(r.stderr.strip().count("\n"), 0, r.stderr)
        self.assertIn("missing column 't'", r.stderr)
        self.assertFalse(os.path.exists(os.path.join(tmp, "x.bag")))


if __name__ == "__main__":
    unittest.main()
