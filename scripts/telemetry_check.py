#!/usr/bin/env python3
"""A scenario's drive streamed as telemetry, identified, over N seeds: for each seed, `pmsm_tool
simulate --telemetry-period P` (means over P seconds, optionally in a log format's layout) and
`pmsm_tool identify --json`; then per parameter the median / worst |error| against the truth, the
seeds reported identified, and those identified more than 2 % off or outside their stated
uncertainty. Progress on stderr; Ctrl-C prints what finished.

  scripts/telemetry_check.py --tool build/ws/devel/lib/pmsm_param_id/pmsm_tool \\
      --scenario config/scenarios/telemetry_duty_cycle.yaml --period 0.02 --seeds 30 [--format vesc]

With --every S (and a --config with a thermal: block, e.g. cold_start.yaml) it checks the
temperatures as a stream would report them: each seed's log is identified up to every S seconds of
it, and each reported winding and magnet temperature is compared with the truth (from the log's
R_s and psi_f columns, relative to the first row, with the scenario's thermal coefficients).
"""
import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

import yaml

PARAMETERS = ("R_s", "L_d", "L_q", "psi_f")


def run_seed(tool, scenario, period, fmt, seed, folder, config="", duration=0.0):
    log = os.path.join(folder, f"seed{seed}.csv")
    out = os.path.join(folder, f"seed{seed}.json")
    sim = [tool, "simulate", "--scenario", scenario, "--csv", log, "--telemetry-period", str(period), "--seed", str(seed)]
    sim += ["--duration", str(duration)] if duration > 0 else []
    ident = [tool, "identify", "--csv", log, "--json", out] + (["--config", config] if config else [])
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


def thermal_seed(tool, scenario, period, config, every, seed, folder, coefficients, duration=0.0):
    """(time, reported winding, its uncertainty, truth, reported magnet, its uncertainty, truth) per prefix."""
    log = os.path.join(folder, f"seed{seed}.csv")
    subprocess.run([tool, "simulate", "--scenario", scenario, "--csv", log, "--telemetry-period", str(period),
                    "--seed", str(seed)] + (["--duration", str(duration)] if duration > 0 else []),
                   check=True, stdout=subprocess.DEVNULL)
    with open(log) as f:
        lines = f.read().splitlines()
    header = lines[0].split(",")
    rows = [line.split(",") for line in lines[1:]]
    t_col, r_col, p_col = header.index("t"), header.index("R_s"), header.index("psi_f")
    r0, p0 = float(rows[0][r_col]), float(rows[0][p_col])
    alpha, beta, t_ref = coefficients
    points = []
    end = float(rows[-1][t_col])
    cut = every
    prefix, out = os.path.join(folder, "prefix.csv"), os.path.join(folder, "prefix.json")
    while cut <= end + 1e-9:
        kept = [r for r in rows if float(r[t_col]) <= cut]
        with open(prefix, "w") as f:
            f.write(lines[0] + "\n" + "\n".join(",".join(r) for r in kept) + "\n")
        subprocess.run([tool, "identify", "--csv", prefix, "--config", config, "--json", out], check=True,
                       stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        with open(out) as f:
            e = json.load(f)
        last = kept[-1]
        points.append((cut, e.get("winding_temperature"), e.get("winding_temperature_uncertainty"),
                       t_ref + (float(last[r_col]) / r0 - 1.0) / alpha,
                       e.get("magnet_temperature"), e.get("magnet_temperature_uncertainty"),
                       t_ref + (float(last[p_col]) / p0 - 1.0) / beta))
        cut += every
    return points


def thermal_table(results):
    """Per temperature: share of prefixes reported, median of per-seed medians and worst |error|, outside stated."""
    print(f"{'temperature':<12} {'reported':>9} {'median |error| K':>17} {'worst seed K':>13} {'worst K':>8} {'outside stated':>15}")
    for name, value, unc, truth in (("winding", 1, 2, 3), ("magnet", 4, 5, 6)):
        reported = total = outside = 0
        medians, worst = [], 0.0
        for points in results:
            errors = []
            for point in points:
                total += 1
                if point[value] is None:
                    continue
                reported += 1
                error = abs(point[value] - point[truth])
                errors.append(error)
                worst = max(worst, error)
                outside += error > point[unc]
            if errors:
                medians.append(statistics.median(errors))
        share = 100.0 * reported / total if total else 0.0
        median = statistics.median(medians) if medians else float("nan")
        worst_seed = max(medians) if medians else float("nan")
        print(f"{name:<12} {share:>8.0f}% {median:>17.2f} {worst_seed:>13.2f} {worst:>8.2f} {outside:>7}/{reported:<7}")


def over_seeds(seeds, run):
    """run(seed, folder) for seeds 1..N in a temporary folder, progress on stderr; Ctrl-C keeps what finished."""
    results = []
    start = time.time()
    try:
        with tempfile.TemporaryDirectory() as folder:
            for seed in range(1, seeds + 1):
                results.append(run(seed, folder))
                left = (time.time() - start) / seed * (seeds - seed)
                print(f"[{seed}/{seeds}] seeds done; about {left:.0f} s left", file=sys.stderr)
    except KeyboardInterrupt:
        print(f"interrupted: {len(results)} of {seeds} seeds finished; the table covers those", file=sys.stderr)
    return results


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--tool", required=True)
    ap.add_argument("--scenario", required=True)
    ap.add_argument("--period", type=float, required=True, help="telemetry period [s]")
    ap.add_argument("--seeds", type=int, default=30)
    ap.add_argument("--format", default="", help="a log format (e.g. vesc) to write and read the telemetry in")
    ap.add_argument("--config", default="", help="identifier YAML (with --every: one with a thermal: block)")
    ap.add_argument("--every", type=float, default=0.0,
                    help="check the temperatures a stream reports, identifying the log up to every EVERY seconds")
    ap.add_argument("--duration", type=float, default=0.0, help="simulate this long instead of the scenario's run.duration [s]")
    args = ap.parse_args()
    if args.every > 0:
        if not args.config or args.format:
            ap.error("--every needs --config (with a thermal: block) and the plain CSV layout (no --format)")
        with open(args.scenario) as f:
            thermal = (yaml.safe_load(f) or {}).get("thermal") or {}
        if "reference_temperature" not in thermal:
            ap.error(f"{args.scenario}: no thermal: block, so no temperatures to check")
        coefficients = (float(thermal.get("copper_coefficient", 3.93e-3)), float(thermal.get("magnet_coefficient", -1.2e-3)),
                        float(thermal["reference_temperature"]))
        results = over_seeds(args.seeds, lambda seed, folder: thermal_seed(
            args.tool, args.scenario, args.period, args.config, args.every, seed, folder, coefficients, args.duration))
        if not results:
            return 1
        print(f"{os.path.basename(args.scenario)} as telemetry every {args.period} s, identified up to every {args.every} s "
              f"with {os.path.basename(args.config)}, {len(results)} seeds")
        thermal_table(results)
        return 0
    results = over_seeds(args.seeds, lambda seed, folder: run_seed(
        args.tool, args.scenario, args.period, args.format, seed, folder, args.config, args.duration))
    if not results:
        return 1
    print(f"{os.path.basename(args.scenario)}{f' ({args.duration:g} s)' if args.duration > 0 else ''} as telemetry every "
          f"{args.period} s{' (' + args.format + ')' if args.format else ''}, {len(results)} seeds")
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
