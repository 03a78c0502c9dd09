#!/usr/bin/env python3
"""The shipped-scenario sweep: every shipped scenario but the two ten-minute ones, 30 seeds, six
methods (24 runs of `pmsm_tool bench`), and the table doc/results.md keeps: per run the final values
reported identified, those more than 2 % off the truth and those outside their stated uncertainty,
and the same along the run (an estimate every 10 ms).

  scripts/sweep.py --tool build/ws/devel/lib/pmsm_param_id/pmsm_tool --out build/sweep/NAME
  scripts/sweep.py --summarise build/sweep/NAME [--compare build/sweep/OTHER]

--compare pairs the two sweeps' records by (run, method, seed) and prints, per run, how many records
differ at all and the median / worst change of |error| of the identified final values [percentage
points]: what a change that moves results only in the last bits (or draws another random stream)
did to them.
"""
import argparse
import json
import os
import statistics
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PARAMETERS = ("R_s", "L_d", "L_q", "psi_f")
# (run name, scenario, identifier config or None); "_rd": the real-drive config, "_sat": the
# saturating-machine config.
RUNS = [(name, name, None) for name in (
    "small_fast", "large_slow", "industrial", "industrial_no_injection", "robot_joint", "robot_joint_no_injection",
    "wc1", "wc2", "wc1_drive", "wc2_drive", "wc1_no_injection", "rs_drift", "demagnetisation", "inter_turn_fault",
    "wc1_realistic", "robot_joint_realistic", "saturated_ipmsm", "saturated_map", "saturated_speed_control")]
RUNS += [("robot_joint_realistic_rd", "robot_joint_realistic", "real_drive.yaml"),
         ("wc1_realistic_rd", "wc1_realistic", "real_drive.yaml"),
         ("saturated_ipmsm_sat", "saturated_ipmsm", "saturating_machine.yaml"),
         ("saturated_map_sat", "saturated_map", "saturating_machine.yaml"),
         ("saturated_speed_control_sat", "saturated_speed_control", "saturating_machine.yaml")]


def run_all(tool, out, seeds):
    os.makedirs(out, exist_ok=True)
    for name, scenario, config in RUNS:
        cmd = [tool, "bench", "--reference", os.path.join(ROOT, "config/reference/paper_tables.csv"),
               "--scenario", os.path.join(ROOT, "config/scenarios", scenario + ".yaml"), "--seeds", str(seeds),
               "--json", os.path.join(out, name + ".json")]
        if config:
            cmd += ["--config", os.path.join(ROOT, "config/identifiers", config)]
        start = time.time()
        with open(os.path.join(out, name + ".txt"), "w") as log:
            subprocess.run(cmd, stdout=log, stderr=subprocess.STDOUT, check=True)
        print(f"{name}: {time.time() - start:.0f} s", file=sys.stderr)


def counts(records):
    """final identified, > 2 % off, outside stated; along the run the same three; the largest ratios."""
    c = dict(final=0, final_wrong=0, final_outside=0, along=0, along_wrong=0, along_outside=0,
             final_ratio=0.0, along_ratio=0.0)
    for r in records:
        for p in PARAMETERS:
            if r["status"][p] != "identified":
                continue
            c["final"] += 1
            error = abs(r["err_" + p]) / 100.0
            c["final_wrong"] += error > 0.02
            stated = r["relative_uncertainty"][p]
            ratio = error / stated if stated else float("inf")
            c["final_outside"] += ratio > 1.0
            c["final_ratio"] = max(c["final_ratio"], ratio)
        along = r.get("along_run") or {}
        for p in PARAMETERS:
            c["along"] += along.get("identified", {}).get(p, 0)
            c["along_wrong"] += along.get("wrong", {}).get(p, 0)
            c["along_outside"] += along.get("outside_stated", {}).get(p, 0)
            ratio = along.get("worst_error_over_stated", {}).get(p)
            if ratio is not None:
                c["along_ratio"] = max(c["along_ratio"], ratio)
    return c


def load(directory, name):
    path = os.path.join(directory, name + ".json")
    if not os.path.exists(path):
        return None
    with open(path) as f:
        return [r for r in json.load(f) if "status" in r and "method" in r]


def summarise(directory):
    print("| run | final identified | > 2 % off | outside stated [largest ratio] | along the run identified | > 2 % off "
          "| outside stated [largest ratio] |")
    print("|---|---|---|---|---|---|---|")
    total = dict(final=0, final_wrong=0, final_outside=0, along=0, along_wrong=0, along_outside=0)
    for name, _, _ in RUNS:
        records = load(directory, name)
        if records is None:
            print(f"| {name} | (missing) ||||||")
            continue
        c = counts(records)
        for k in total:
            total[k] += c[k]
        print(f"| {name} | {c['final']} | {c['final_wrong']} | {c['final_outside']} [{c['final_ratio']:.2f}] | "
              f"{c['along']} | {c['along_wrong']} | {c['along_outside']} [{c['along_ratio']:.2f}] |")
    print(f"| all | {total['final']} | {total['final_wrong']} | {total['final_outside']} | {total['along']} | "
          f"{total['along_wrong']} | {total['along_outside']} |")


def compare(directory, other):
    print("| run | records | differing | identified final values paired | median / worst change of |error| [pp] |")
    print("|---|---|---|---|---|")
    for name, _, _ in RUNS:
        a, b = load(directory, name), load(other, name)
        if a is None or b is None:
            continue
        keyed = {(r["method"], r["seed"]): r for r in b}
        differing, changes = 0, []
        for r in a:
            s = keyed.get((r["method"], r["seed"]))
            if s is None:
                continue
            if any(r[p] != s[p] for p in PARAMETERS) or r["status"] != s["status"]:
                differing += 1
            for p in PARAMETERS:
                if r["status"][p] == "identified" and s["status"][p] == "identified":
                    changes.append(abs(r["err_" + p]) - abs(s["err_" + p]))
        median = statistics.median(changes) if changes else 0.0
        worst = max(changes, key=abs) if changes else 0.0
        print(f"| {name} | {len(a)} | {differing} | {len(changes)} | {median:+.4f} / {worst:+.4f} |")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--tool", help="pmsm_tool binary: run the sweep")
    ap.add_argument("--out", help="folder for the runs' JSON and text output")
    ap.add_argument("--seeds", type=int, default=30)
    ap.add_argument("--summarise", help="a sweep's folder: print its table")
    ap.add_argument("--compare", help="a second sweep's folder: pair its records with the first's")
    args = ap.parse_args()
    if args.tool:
        if not args.out:
            ap.error("--tool needs --out")
        run_all(args.tool, args.out, args.seeds)
        summarise(args.out)
    elif args.summarise:
        summarise(args.summarise)
        if args.compare:
            print()
            compare(args.summarise, args.compare)
    else:
        ap.error("give --tool and --out, or --summarise")


if __name__ == "__main__":
    main()
