#!/usr/bin/env python3
"""The shipped-scenario sweep: every shipped scenario shorter than ten seconds with no identifier
config, every shipped identifier config on every scenario with an inverter, and the saturating-
machine config on the saturating scenarios; 30 seeds, six methods, one `pmsm_tool bench` each. It
prints the tables doc/results.md keeps: FBDAPSO's median / worst |error| per parameter with the seeds
where it is identified, and per run the final values reported identified, those more than 2 % off
the truth and those outside their stated uncertainty, and the same along the run (an estimate every
10 ms). Progress goes to stderr; Ctrl-C stops after saying which runs finished (their tables print).

  scripts/sweep.py --tool build/ws/devel/lib/pmsm_param_id/pmsm_tool --out build/sweep/NAME
  scripts/sweep.py --summarise build/sweep/NAME [--compare build/sweep/OTHER]

--compare pairs the two sweeps' records by (run, method, seed) and prints, per run, how many records
differ at all and the median / worst change of |error| of the identified final values [percentage
points]: what a change that moves results only in the last bits (or draws another random stream)
did to them.
"""
import argparse
import glob
import json
import os
import statistics
import subprocess
import sys
import time

import yaml

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PARAMETERS = ("R_s", "L_d", "L_q", "psi_f")
# Runs of ten seconds of drive time or more (the monitoring runs: the two ten-minute ones on ideal
# drives, the three of the switching-level drive) are left to their own bench with --monitor; at
# 30 seeds and six methods each would take minutes of the sweep.
LONG_RUN_S = 10.0
# Identifier configs run on every scenario with an inverter (suffix of the run's name). paper.yaml is
# left out: its search box is the paper's motor's; default.yaml is what no config gives.
INVERTER_CONFIGS = [("real_drive.yaml", "_rd"), ("cold_start.yaml", "_cold"), ("saturating_machine.yaml", "_sat")]
# The saturating-machine config on the saturating scenarios.
SATURATING = ["saturated_ipmsm", "saturated_map", "saturated_speed_control"]


def shipped_runs():
    """(run name, scenario, identifier config or None): every shipped scenario shorter than LONG_RUN_S
    with no config, then every INVERTER_CONFIGS config on those with an `inverter:` block, then the
    saturating-machine config on SATURATING."""
    plain, with_config = [], []
    for path in sorted(glob.glob(os.path.join(ROOT, "config/scenarios/*.yaml"))):
        with open(path) as f:
            scenario = yaml.safe_load(f) or {}
        if (scenario.get("run") or {}).get("duration", 0.0) >= LONG_RUN_S:
            continue
        name = os.path.splitext(os.path.basename(path))[0]
        plain.append((name, name, None))
        if "inverter" in scenario:
            with_config += [(name + suffix, name, config) for config, suffix in INVERTER_CONFIGS]
    with_config += [(name + "_sat", name, "saturating_machine.yaml") for name in SATURATING
                    if (name + "_sat", name, "saturating_machine.yaml") not in with_config]
    return plain + with_config


RUNS = shipped_runs()


def run_all(tool, out, seeds):
    os.makedirs(out, exist_ok=True)
    started = time.time()
    finished = []
    try:
        for i, (name, scenario, config) in enumerate(RUNS):
            cmd = [tool, "bench", "--reference", os.path.join(ROOT, "config/reference/paper_tables.csv"),
                   "--scenario", os.path.join(ROOT, "config/scenarios", scenario + ".yaml"), "--seeds", str(seeds),
                   "--json", os.path.join(out, name + ".json")]
            if config:
                cmd += ["--config", os.path.join(ROOT, "config/identifiers", config)]
            start = time.time()
            with open(os.path.join(out, name + ".txt"), "w") as log:
                subprocess.run(cmd, stdout=log, stderr=subprocess.DEVNULL, check=True)
            finished.append(name)
            elapsed = time.time() - started
            left = elapsed / len(finished) * (len(RUNS) - len(finished))
            print(f"[{len(finished)}/{len(RUNS)}] {name}: {time.time() - start:.0f} s; about {left / 60:.0f} min left",
                  file=sys.stderr)
    except KeyboardInterrupt:
        print(f"\ninterrupted: {len(finished)} of {len(RUNS)} runs finished"
              f"{' (' + ', '.join(finished) + ')' if finished else ''}; their tables follow", file=sys.stderr)
        return False
    return True


def fbdapso_table(directory):
    """FBDAPSO's final values per run: median / worst |error| [%] and [seeds identified / seeds]."""
    print("| run | FBDAPSO R_s | L_d | L_q | psi_f | real drive's model (seeds) |")
    print("|---|---|---|---|---|---|")
    for name, _, _ in RUNS:
        records = load(directory, name)
        if records is None:
            continue
        fb = [r for r in records if r["method"] == "fbdapso"]
        if not fb:
            continue
        cells = []
        for p in PARAMETERS:
            errors = [abs(r["err_" + p]) for r in fb if r["err_" + p] is not None]
            identified = sum(1 for r in fb if r["status"][p] == "identified")
            cells.append(f"{statistics.median(errors):.2f} / {max(errors):.2f} [{identified}/{len(fb)}]" if errors
                         else f"- [{identified}/{len(fb)}]")
        switched = sum(1 for r in fb if (r.get("drive_model") or "").startswith("real drive, from the data"))
        print(f"| {name} | " + " | ".join(cells) + f" | {switched} |")


def counts(records):
    """final identified, > 2 % off, outside stated; along the run the same three; the largest ratios."""
    c = dict(final=0, final_wrong=0, final_outside=0, along=0, along_wrong=0, along_outside=0,
             final_ratio=0.0, along_ratio=0.0)
    for r in records:
        for p in PARAMETERS:
            if r["status"][p] != "identified":
                continue
            c["final"] += 1
            c["final_wrong"] += r["confidently_wrong"][p]  # the bench's definition: identified, > 2 % off
            error = abs(r["err_" + p]) / 100.0
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
        complete = run_all(args.tool, args.out, args.seeds)
        fbdapso_table(args.out)
        print()
        summarise(args.out)
        if not complete:
            sys.exit(130)
    elif args.summarise:
        fbdapso_table(args.summarise)
        print()
        summarise(args.summarise)
        if args.compare:
            print()
            compare(args.summarise, args.compare)
    else:
        ap.error("give --tool and --out, or --summarise")


if __name__ == "__main__":
    main()
