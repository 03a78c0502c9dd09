#!/usr/bin/env python3
"""A scenario's drive streamed as telemetry, identified, over N seeds: for each seed, `pmsm_tool
simulate --telemetry-period P` (means over P seconds, optionally in a log format's layout) and
`pmsm_tool identify --json`; then per parameter the median / worst |error| against the truth, the
seeds reported identified, and those identified more than 2 % off or outside their stated
uncertainty. Progress on stderr; Ctrl-C prints what finished.

  scripts/telemetry_check.py --tool build/ws/devel/lib/pmsm_param_id/pmsm_tool \\
      --scenario config/scenarios/telemetry_duty_cycle.yaml --period 0.02 --seeds 30 [--format vesc]
"""
import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

PARAMETERS = ("R_s", "L_d", "L_q", "psi_f")


def run_seed(tool, scenario, period, fmt, seed, folder):
    log = os.path.join(folder, f"seed{seed}.csv")
    out = os.path.join(folder, f"seed{seed}.json")
    sim = [tool, "simulate", "--scenario", scenario, "--csv", log, "--telemetry-period", str(period), "--seed", str(seed)]
    ident = [tool, "identify", "--csv", log, "--json", out]
    if fmt:
        sim += ["--format", fmt]
        ident += ["--format", fmt]
    subprocess.run(sim, check=True, stdout=subprocess.DEVNULL)
    subprocess.run(ident, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    with open(out) as f:
        estimate = json.load(f)
    # The truth at the log's end: the last row's R_s, L_d, L_q, psi_f columns.
    with open(log) as f:
        lines = f.read().splitlines()
    separator = ";" if ";" in lines[0] else ","
    header = lines[0].split(separator)
    last = lines[-1].split(separator)
    truth = {p: float(last[header.index(p)]) for p in PARAMETERS}
    return estimate, truth


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--tool", required=True)
    ap.add_argument("--scenario", required=True)
    ap.add_argument("--period", type=float, required=True, help="telemetry period [s]")
    ap.add_argument("--seeds", type=int, default=30)
    ap.add_argument("--format", default="", help="a log format (e.g. vesc) to write and read the telemetry in")
    args = ap.parse_args()
    results = []
    start = time.time()
    try:
        with tempfile.TemporaryDirectory() as folder:
            for seed in range(1, args.seeds + 1):
                results.append(run_seed(args.tool, args.scenario, args.period, args.format, seed, folder))
                left = (time.time() - start) / seed * (args.seeds - seed)
                print(f"[{seed}/{args.seeds}] seeds done; about {left:.0f} s left", file=sys.stderr)
    except KeyboardInterrupt:
        print(f"interrupted: {len(results)} of {args.seeds} seeds finished; the table covers those", file=sys.stderr)
    if not results:
        return 1
    print(f"{os.path.basename(args.scenario)} as telemetry every {args.period} s{' (' + args.format + ')' if args.format else ''}, "
          f"{len(results)} seeds")
    print(f"{'parameter':<10} {'median |error| %':>17} {'worst %':>8} {'identified':>11} {'> 2 % off':>10} {'outside stated':>15}")
    for p in PARAMETERS:
        errors, identified, wrong, outside = [], 0, 0, 0
        for estimate, truth in results:
            error = abs(100.0 * (estimate[p] - truth[p]) / truth[p]) if estimate[p] is not None else float("inf")
            errors.append(error)
            if estimate["status"][p] == "identified":
                identified += 1
                wrong += error > 2.0
                stated = estimate["relative_uncertainty"][p]
                outside += stated is None or error > 100.0 * stated
        print(f"{p:<10} {statistics.median(errors):>17.3f} {max(errors):>8.3f} {identified:>6}/{len(results):<4} {wrong:>10} {outside:>15}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
