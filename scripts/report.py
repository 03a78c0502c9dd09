#!/usr/bin/env python3
"""Turns a bag into figures and the paper's table.

    report.py BAG [--out DIR] [--reference CSV] [--condition wc1|wc2|auto|none]

Reads the estimates (*/estimate, pmsm_param_id/ParameterEstimate), the condition monitor's
events (*/events, pmsm_param_id/ConditionEvent), the maps of the motor (*/map,
pmsm_param_id/ParameterMap) and, when present, the true parameters
(/drive/true_parameters) and samples (/drive/samples_batch). Writes DIR/R_s.png, L_d.png, L_q.png,
psi_f.png (every method against truth, as the paper's Figs. 5-6, 8-9), DIR/fitness.png (Figs. 7
and 10), DIR/alarms.png (alarm timeline), DIR/temperatures.png (winding and magnet temperatures
against truth, when any estimate carries one), DIR/map.png (each map's identified L_d, L_q, psi_f
against i_q and the truth) and DIR/report.md (Table 2/3 layout with the paper's numbers beside
ours, temperatures, every alarm, every map cell). Works on bags from demo.launch, replay.launch and csv2bag + replay.
"""
import argparse
import bisect
import csv
import math
import os
import sys

PARAMS = ["R_s", "L_d", "L_q", "psi_f"]
UNITS = {"R_s": "ohm", "L_d": "H", "L_q": "H", "psi_f": "Wb"}
ORDER = ["fbdapso", "sapso", "pso", "ekf", "rls"]
COLORS = {"fbdapso": "tab:red", "sapso": "tab:orange", "pso": "tab:green", "ekf": "tab:blue", "rls": "tab:purple"}
TOLERANCE = 0.01  # recognition band, relative


class BagData:
    def __init__(self):
        self.estimates = {}   # method -> list of (t, msg)
        self.truth = []       # list of (t, (R_s, L_d, L_q, psi_f)), sorted by t
        self.truth_times = [] # the t of each truth entry, for bisect
        self.truth_temperatures = []  # list of (t, winding, magnet) [degC], NaN when unknown
        self.events = []      # list of (t, method, kind, raised, text) from the condition monitors
        self.maps = {}        # method -> the latest pmsm_param_id/ParameterMap message (section 12)
        self.speeds = []      # electrical speed samples [rad/s]
        self.origin = None    # first stamp [ns]
        self.missing = []     # what the bag lacks, in words


def read_bag(path, namespace=""):
    """The estimates, truth, events, maps and speeds of one drive, found by message type (any
    namespace: /drive/..., a fleet's /motor_N/...); `namespace` picks one drive where there are several."""
    import rosbag  # Debian's python3-rosbag
    data = BagData()
    try:
        bag = rosbag.Bag(path)
    except Exception as e:  # rosbag raises several types for "not a bag"
        print("error: %s: not a readable bag (%s)" % (path, e), file=sys.stderr)
        sys.exit(2)
    with bag:
        topics = bag.get_type_and_topic_info().topics
        prefix = namespace.rstrip("/") + "/" if namespace else ""

        def of_type(t):
            return sorted(name for name, info in topics.items()
                          if info.msg_type == "pmsm_param_id/" + t and name.startswith(prefix))
        est_topics = of_type("ParameterEstimate")
        event_topics = set(of_type("ConditionEvent"))
        map_topics = of_type("ParameterMap")
        truth_topics = of_type("ElectricalParameters")
        sample_topics = of_type("DriveSampleBatch")
        if len(truth_topics) > 1 or len(sample_topics) > 1:
            print("error: %s: several drives in this bag (%s): choose one with --namespace" %
                  (path, ", ".join(truth_topics or sample_topics)), file=sys.stderr)
            sys.exit(2)
        # Latched, growing: keep the latest. (An empty topic list would read every topic.)
        for _, msg, _ in (bag.read_messages(topics=map_topics) if map_topics else []):
            data.maps[msg.method] = msg
        raw = []
        wanted = est_topics + sorted(event_topics) + truth_topics + sample_topics
        for topic, msg, _ in (bag.read_messages(topics=wanted) if wanted else []):
            stamp = msg.header.stamp.to_nsec()
            data.origin = stamp if data.origin is None else min(data.origin, stamp)
            raw.append((topic, msg, stamp))
    if data.origin is None:
        data.origin = 0
    for topic, msg, stamp in raw:
        t = (stamp - data.origin) * 1e-9
        if topic in truth_topics:
            data.truth.append((t, (msg.R_s, msg.L_d, msg.L_q, msg.psi_f)))
            data.truth_temperatures.append((t, getattr(msg, "winding_temperature", float("nan")),
                                            getattr(msg, "magnet_temperature", float("nan"))))
        elif topic in event_topics:
            data.events.append((t, msg.method, msg.kind, msg.raised, msg.text))
        elif topic in sample_topics:
            data.speeds.extend(msg.omega_e[-1:])
        else:
            data.estimates.setdefault(msg.method, []).append((t, msg))
    for m in data.estimates.values():
        m.sort(key=lambda x: x[0])
    data.truth.sort(key=lambda x: x[0])
    data.truth_temperatures.sort(key=lambda x: x[0])
    data.events.sort(key=lambda x: x[0])
    data.truth_times = [t for t, _ in data.truth]
    if not data.estimates:
        data.missing.append("no estimates (no pmsm_param_id/ParameterEstimate topic)")
    else:
        absent = [m for m in ORDER if m not in data.estimates]
        if absent:
            data.missing.append("no estimates from " + ", ".join(absent))
    if not data.truth:
        data.missing.append("no true parameters (no pmsm_param_id/ElectricalParameters topic): errors and recognition "
                            "times cannot be computed")
    return data


def truth_at(data, t):
    """Latest true parameter vector stamped at or before t (or the first one)."""
    if not data.truth:
        return None
    i = bisect.bisect_right(data.truth_times, t + 1e-12)  # entries stamped <= t
    return data.truth[max(i - 1, 0)][1]


def values(msg):
    return (msg.R_s, msg.L_d, msg.L_q, msg.psi_f)


def recognition_time(data, trace):
    """First time after which every parameter flagged identifiable at the end stays within 1 %."""
    if not trace or not data.truth:
        return None
    selected = [i for i in range(4) if trace[-1][1].identifiable[i]]
    if not selected:
        return None
    first_inside = None
    for t, msg in reversed(trace):
        true = truth_at(data, t)
        v = values(msg)
        if all(abs(v[i] - true[i]) <= TOLERANCE * abs(true[i]) for i in selected):
            first_inside = t
        else:
            break
    return first_inside


def paper_rows(reference, condition):
    rows = {}
    if not reference or not condition or not os.path.exists(reference):
        return rows
    with open(reference) as f:
        lines = [l for l in f if l.strip() and not l.startswith("#")]
    for r in csv.DictReader(lines):
        if r["condition"] == condition:
            rows[r["method"].lower()] = r
    return rows


def detect_condition(data):
    if not data.speeds:
        return None
    rpm = sum(data.speeds[-20:]) / len(data.speeds[-20:]) / 4 * 60 / (2 * math.pi)
    for name, target in (("wc1", 1000.0), ("wc2", 1200.0)):
        if abs(rpm - target) < 0.02 * target:
            return name
    return None


STATUS_CONSTANTS = ("NO_DATA", "IDENTIFIED", "NOT_EXCITED", "POOR_FIT", "AT_BOUND", "IMPLAUSIBLE", "NOT_CONVERGED")


def status_names(msg):
    """Per-parameter status names, named by ParameterEstimate.msg's own constants."""
    codes = list(getattr(msg, "status", []) or [])
    if len(codes) != 4:  # bags recorded before statuses existed
        return ["identified" if ok else "not_identified" for ok in msg.identifiable]
    names = {getattr(type(msg), c, i): c.lower() for i, c in enumerate(STATUS_CONSTANTS)}
    return [names.get(c, "status %d" % c) for c in codes]


def summarize(data):
    """{method: dict(final values, errors, identifiable, recognition time, fitness)} from the bag."""
    out = {}
    for method, trace in data.estimates.items():
        t, last = trace[-1]
        true = truth_at(data, t)
        row = {"values": values(last), "identifiable": list(last.identifiable), "status": status_names(last),
               "likely_cause": getattr(last, "fit_likely_cause", ""), "fitness": last.fitness,
               "samples": last.samples_used, "skipped": last.samples_skipped, "t": t}
        row["errors"] = [100.0 * (v - p) / p for v, p in zip(row["values"], true)] if true else None
        row["recognition_time"] = recognition_time(data, trace)
        row["temperatures"] = [(getattr(last, "winding_temperature", float("nan")),
                                getattr(last, "winding_temperature_uncertainty", float("nan"))),
                               (getattr(last, "magnet_temperature", float("nan")),
                                getattr(last, "magnet_temperature_uncertainty", float("nan")))]
        out[method] = row
    return out


def fmt(x, spec):
    return "n/a" if x is None or (isinstance(x, float) and not math.isfinite(x)) else format(x, spec)


def finite(x):
    return isinstance(x, float) and math.isfinite(x)


def has_temperatures(data):
    """Any estimate or truth message carries a temperature."""
    return any(finite(w) or finite(m) for _, w, m in data.truth_temperatures) or any(
        finite(getattr(msg, "winding_temperature", float("nan"))) or finite(getattr(msg, "magnet_temperature", float("nan")))
        for trace in data.estimates.values() for _, msg in trace)


def temperature_lines(data, summary, methods):
    if not has_temperatures(data):
        return ["Temperatures: none (the identifiers had no `thermal:` block; doc/algorithm.md section 9).", ""]
    true_w, true_m = (data.truth_temperatures[-1][1:] if data.truth_temperatures else (float("nan"), float("nan")))
    lines = ["Temperatures at the end [degC] (from R_s and psi_f while identified; n/a = not identified):", "",
             "| | truth | " + " | ".join(methods) + " |", "|" + "---|" * (len(methods) + 2)]
    for k, (name, true) in enumerate((("winding", true_w), ("magnet", true_m))):
        cells = [name, fmt(true, ".1f")]
        for m in methods:
            value, unc = summary[m]["temperatures"][k]
            cells.append("%s +- %s" % (fmt(value, ".1f"), fmt(unc, ".1f")) if finite(value) else "n/a")
        lines.append("| " + " | ".join(cells) + " |")
    return lines + [""]


def alarm_lines(data):
    if not data.events:
        return ["Alarms: none raised by any method (condition monitor, doc/algorithm.md section 9).", ""]
    lines = ["Alarms (condition monitor, doc/algorithm.md section 9):", "", "| t [s] | method | alarm | | what |",
             "|---|---|---|---|---|"]
    for t, method, kind, raised, text in data.events:
        lines.append("| %.3f | %s | %s | %s | %s |" % (t, method, kind, "raised" if raised else "cleared", text))
    return lines + [""]


def cell_truth(data, cell, i):
    """The truth of parameter i when a map cell's identified value was filed (None without truth)."""
    true = truth_at(data, (cell.identified_stamp[i].to_nsec() - data.origin) * 1e-9)
    return true[i] if true else None


def map_points(data, method):
    """Per identified (cell, parameter) of a method's map: (i_q, parameter index, value, truth or None)."""
    msg = data.maps.get(method)
    return [(cell.identified_i_q[i], i, cell.identified[i], cell_truth(data, cell, i))
            for cell in (msg.cells if msg else []) for i in range(len(PARAMS)) if finite(cell.identified[i])]


def map_lines(data, methods):
    """The online map of the motor: every cell's identified values against the truth at their time."""
    if not data.maps:
        return []
    lines = ["Map of the motor (doc/algorithm.md section 12): per cell of operating points, the latest value "
             "reported identified there and its error against the truth of that moment; - never identified. "
             "L_d incremental, L_q = psi_q / i_q, psi_f = psi_d at i_d = 0.", "",
             "| method | i_d [A] | i_q [A] | estimates | " + " | ".join("%s [%s] (err %%)" % (p, UNITS[p]) for p in PARAMS) + " |",
             "|" + "---|" * (4 + len(PARAMS))]
    for m in [m for m in methods if m in data.maps] + sorted(m for m in data.maps if m not in methods):
        msg = data.maps[m]
        for cell in msg.cells:
            cells = [m, "%.2f" % cell.i_d, "%.2f" % cell.i_q, "%d" % cell.estimates]
            for i in range(len(PARAMS)):
                if not finite(cell.identified[i]):
                    cells.append("-")
                    continue
                true = cell_truth(data, cell, i)
                err = 100.0 * (cell.identified[i] / true - 1.0) if true else None
                cells.append("%s (%s)" % (fmt(cell.identified[i], ".5g"), fmt(err, "+.2f")))
            lines.append("| " + " | ".join(cells) + " |")
        lines.append("| %s | %d estimates not filed (their window spanned a load change) | | | | | | |"
                     % (m, msg.transient_estimates))
    return lines + [""]


def write_markdown(path, bag_path, data, summary, paper, condition):
    methods = [m for m in ORDER if m in summary] + sorted(m for m in summary if m not in ORDER)
    lines = ["# Identification report", "", "Bag: `%s`" % os.path.basename(bag_path), ""]
    if data.missing:
        lines += ["**Missing from this bag:** " + "; ".join(data.missing) + ".", ""]
    if not methods:
        lines += ["Nothing to tabulate.", ""]
    else:
        true = data.truth[-1][1] if data.truth else None
        lines += ["Final estimates (value, error against truth in %%, status when not identified). %s" % (
            "Paper columns: the seed paper's table for %s (mean of 5 runs, T_s = 1e-6 s)." % condition
            if paper else "No paper condition matches this run."), ""]
        header = ["Parameter", "truth"] + methods + (["paper " + m for m in methods if m in paper])
        lines += ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
        for i, p in enumerate(PARAMS):
            cells = ["%s [%s]" % (p, UNITS[p]), fmt(true[i] if true else None, ".6g")]
            for m in methods:
                s = summary[m]
                err = s["errors"][i] if s["errors"] else None
                cells.append("%s (%s %%)%s" % (fmt(s["values"][i], ".6g"), fmt(err, "+.3f"),
                                               "" if s["identifiable"][i] else " **" + s["status"][i] + "**"))
            for m in methods:
                if m in paper:
                    cells.append("%s (%s %%)" % (paper[m][p], paper[m][p + "_err"]))
            lines.append("| " + " | ".join(cells) + " |")
        cells = ["recognition time [s]", ""] + [fmt(summary[m]["recognition_time"], ".4f") for m in methods]
        cells += [paper[m]["recognition_time"] for m in methods if m in paper]
        lines.append("| " + " | ".join(cells) + " |")
        cells = ["fitness [A^2]", ""] + [fmt(summary[m]["fitness"], ".4g") for m in methods]
        cells += [paper[m]["fitness"] or "n/a" for m in methods if m in paper]
        lines.append("| " + " | ".join(cells) + " |")
        cells = ["samples used / skipped", ""] + ["%d / %d" % (summary[m]["samples"], summary[m]["skipped"]) for m in methods]
        cells += ["" for m in methods if m in paper]
        lines.append("| " + " | ".join(cells) + " |")
        lines += ["", "Recognition time: the first time after which every parameter identified at the end "
                  "stays within 1 % of truth (doc/algorithm.md), to the resolution of the estimates in the bag "
                  "(the identifiers' ~publish_period: 10 ms by default). The paper's fitness is on its own scale.", ""]
        causes = ["- %s: %s" % (m, summary[m]["likely_cause"]) for m in methods if summary[m]["likely_cause"]]
        if causes:
            lines += ["The model does not fit the data; likely cause:"] + causes + [""]
    lines += temperature_lines(data, summary, methods) + alarm_lines(data) + map_lines(data, methods)
    figures = ["[%s](%s.png)" % (p, p) for p in PARAMS] + ["[fitness](fitness.png)", "[alarms](alarms.png)"]
    if has_temperatures(data):
        figures.append("[temperatures](temperatures.png)")
    if data.maps:
        figures.append("[map](map.png)")
    lines += ["Figures: " + ", ".join(figures), ""]
    with open(path, "w") as f:
        f.write("\n".join(lines))


def draw(out_dir, data):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    written = []
    for i, p in enumerate(PARAMS):
        fig, ax = plt.subplots(figsize=(8, 4.2), dpi=100)
        if data.truth:
            ax.step([t for t, _ in data.truth], [v[i] for _, v in data.truth], where="post", color="black",
                    linewidth=2.0, label="truth")
        for m in [m for m in ORDER if m in data.estimates] + [m for m in data.estimates if m not in ORDER]:
            trace = data.estimates[m]
            ts = [t for t, _ in trace]
            vs = [values(msg)[i] for _, msg in trace]
            ok = [msg.identifiable[i] for _, msg in trace]
            ax.plot(ts, vs, color=COLORS.get(m), linewidth=1.2, label=m)
            # parameters the data do not determine: shown as grey dots on top
            bad = [(t, v) for t, v, o in zip(ts, vs, ok) if not o]
            if bad:
                ax.plot([b[0] for b in bad], [b[1] for b in bad], ".", color="grey", markersize=2)
        if data.truth:
            ref = data.truth[-1][1][i]
            ax.set_ylim(ref * 0.8, ref * 1.2)
        ax.set_xlabel("time [s]")
        ax.set_ylabel("%s [%s]" % (p, UNITS[p]))
        ax.set_title("%s: estimates against truth (grey dots: not identified)" % p)
        ax.grid(True, alpha=0.3)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(loc="upper right", fontsize=8)
        fig.tight_layout()
        name = os.path.join(out_dir, p + ".png")
        fig.savefig(name)
        plt.close(fig)
        written.append(name)
    fig, ax = plt.subplots(figsize=(8, 4.2), dpi=100)
    for m in [m for m in ORDER if m in data.estimates]:
        trace = [(t, msg.fitness) for t, msg in data.estimates[m] if math.isfinite(msg.fitness) and msg.fitness > 0]
        if trace:
            ax.semilogy([t for t, _ in trace], [f for _, f in trace], color=COLORS.get(m), linewidth=1.0, label=m)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("fitness [A^2]")
    ax.set_title("Fitness (mean squared block current error) at each method's estimate")
    ax.grid(True, alpha=0.3)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    name = os.path.join(out_dir, "fitness.png")
    fig.savefig(name)
    plt.close(fig)
    written.append(name)
    written.append(draw_alarms(plt, out_dir, data))
    if has_temperatures(data):
        written.append(draw_temperatures(plt, out_dir, data))
    if data.maps:
        written.append(draw_map(plt, out_dir, data))
    return written


ALARM_KINDS = ["winding_over_temperature", "demagnetisation", "parameter_jump", "fast_drift"]
ALARM_COLORS = {"winding_over_temperature": "tab:red", "demagnetisation": "tab:purple",
                "parameter_jump": "tab:orange", "fast_drift": "tab:olive"}


def draw_alarms(plt, out_dir, data):
    """One row per method: a bar from each raise to its clear (or to the end of the run)."""
    methods = [m for m in ORDER if m in data.estimates] + sorted(
        set(m for m in data.estimates if m not in ORDER) | set(e[1] for e in data.events if e[1] not in ORDER))
    end = max([trace[-1][0] for trace in data.estimates.values()] + [e[0] for e in data.events] + [0.0])
    fig, ax = plt.subplots(figsize=(8, 1.2 + 0.45 * max(1, len(methods))), dpi=100)
    drawn = set()
    for row, m in enumerate(methods):
        open_since = {}
        for t, method, kind, raised, _ in data.events:
            if method != m:
                continue
            if raised and kind not in open_since:
                open_since[kind] = t
            elif not raised and kind in open_since:
                a = open_since.pop(kind)
                ax.barh(row, max(t - a, end * 0.003), left=a, height=0.6, color=ALARM_COLORS.get(kind, "k"),
                        label=None if kind in drawn else kind)
                drawn.add(kind)
        for kind, a in open_since.items():
            ax.barh(row, max(end - a, end * 0.003), left=a, height=0.6, color=ALARM_COLORS.get(kind, "k"),
                    label=None if kind in drawn else kind)
            drawn.add(kind)
    ax.set_yticks(range(len(methods)))
    ax.set_yticklabels(methods)
    ax.set_xlim(0, end if end > 0 else 1)
    ax.set_ylim(-0.6, max(1, len(methods)) - 0.4)
    ax.set_xlabel("time [s]")
    ax.set_title("Alarms (condition monitor)" if data.events else "Alarms: none raised")
    ax.grid(True, axis="x", alpha=0.3)
    if drawn:
        ax.legend(loc="upper left", fontsize=7)
    fig.tight_layout()
    name = os.path.join(out_dir, "alarms.png")
    fig.savefig(name)
    plt.close(fig)
    return name


def draw_temperatures(plt, out_dir, data):
    fig, axes = plt.subplots(2, 1, figsize=(8, 6), dpi=100, sharex=True)
    for k, (ax, name) in enumerate(zip(axes, ("winding", "magnet"))):
        truth = [(t, v[k]) for t, *v in data.truth_temperatures if finite(v[k])]
        if truth:
            ax.plot([t for t, _ in truth], [v for _, v in truth], color="black", linewidth=2.0, label="truth")
        for m in [m for m in ORDER if m in data.estimates] + [m for m in data.estimates if m not in ORDER]:
            field = name + "_temperature"
            pts = [(t, getattr(msg, field, float("nan"))) for t, msg in data.estimates[m]]
            pts = [(t, v) for t, v in pts if finite(v)]
            if pts:
                ax.plot([t for t, _ in pts], [v for _, v in pts], ".", markersize=2, color=COLORS.get(m), label=m)
        ax.set_ylabel("%s [degC]" % name)
        ax.grid(True, alpha=0.3)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(loc="upper left", fontsize=8)
    axes[0].set_title("Temperatures from R_s and psi_f (only while identified) against truth")
    axes[1].set_xlabel("time [s]")
    fig.tight_layout()
    name = os.path.join(out_dir, "temperatures.png")
    fig.savefig(name)
    plt.close(fig)
    return name


def draw_map(plt, out_dir, data):
    """L_d, L_q and psi_f against i_q from every method's map, with the truth at the same moments."""
    fig, axes = plt.subplots(3, 1, figsize=(8, 8), dpi=100, sharex=True)
    methods = [m for m in ORDER if m in data.maps] + sorted(m for m in data.maps if m not in ORDER)
    for k, i in enumerate((1, 2, 3)):
        ax = axes[k]
        truth = sorted((q, true) for m in methods for q, p, _, true in map_points(data, m) if p == i and true)
        if truth:
            ax.plot([q for q, _ in truth], [v for _, v in truth], "x", color="black", markersize=9, label="truth")
        for m in methods:
            pts = [(q, v) for q, p, v, _ in map_points(data, m) if p == i]
            if pts:
                ax.plot([q for q, _ in pts], [v for _, v in pts], "o", color=COLORS.get(m), markersize=4,
                        fillstyle="none", label=m)
        ax.set_ylabel("%s [%s]" % (PARAMS[i], UNITS[PARAMS[i]]))
        ax.grid(True, alpha=0.3)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(loc="best", fontsize=8)
    axes[0].set_title("Map of the motor: identified values per cell against truth")
    axes[-1].set_xlabel("operating i_q [A]")
    fig.tight_layout()
    name = os.path.join(out_dir, "map.png")
    fig.savefig(name)
    plt.close(fig)
    return name


def main(argv=None):
    here = os.path.dirname(os.path.abspath(__file__))
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("bag")
    parser.add_argument("--out", help="output folder (default: BAG without .bag, plus _report)")
    parser.add_argument("--reference", default=os.path.join(here, "..", "config", "reference", "paper_tables.csv"))
    parser.add_argument("--namespace", default="",
                        help="the drive's namespace where the bag holds several (e.g. /motor_3)")
    parser.add_argument("--condition", default="auto", choices=("wc1", "wc2", "auto", "none"),
                        help="the paper's working condition to compare with: wc1, wc2, auto (from the speed) or none")
    args = parser.parse_args(argv)  # a bad option: argparse's message and exit status 2
    if not os.path.isfile(args.bag):
        print("error: %s: no such file" % args.bag, file=sys.stderr)
        return 2
    if args.condition != "none" and not os.path.isfile(args.reference):
        print("error: --reference: cannot read '%s' (or give --condition none)" % args.reference, file=sys.stderr)
        return 2
    out = args.out or os.path.splitext(args.bag)[0] + "_report"
    try:
        os.makedirs(out, exist_ok=True)
    except OSError as e:
        print("error: --out: cannot create '%s': %s" % (out, e.strerror), file=sys.stderr)
        return 2
    data = read_bag(args.bag, args.namespace)
    condition = detect_condition(data) if args.condition == "auto" else (None if args.condition == "none" else args.condition)
    summary = summarize(data)
    draw(out, data)
    report = os.path.join(out, "report.md")
    write_markdown(report, args.bag, data, summary, paper_rows(args.reference, condition), condition)
    for m in data.missing:
        print("warning: %s: %s" % (args.bag, m), file=sys.stderr)
    print("report: " + report)
    if not data.estimates:  # what exists is drawn, but a report without estimates is a failed report
        print("error: %s: no ParameterEstimate messages: nothing was identified (is an identifier "
              "recording to this bag?)" % args.bag, file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
