#!/usr/bin/env python3
"""Runs fleet.launch and measures whether every identifier keeps up in real time.

    fleet_measure.py --motors N --duration S [--method fbdapso] [--processes] [--threads 4] [--substeps 2] [--json OUT]

Per motor: samples processed / published and the latency of each estimate (arrival wall time minus
the stamp of its last sample: it grows without bound when a backlog builds). With nodelets (the
default) the CPU and resident memory (RSS) of the one manager process that runs every plant and
identifier; with --processes those of each identifier process; sampled every 2 s from /proc.
Progress (motors done, time left) goes to stderr.
"""
import argparse
import json
import os
import statistics
import subprocess
import sys
import time

PAGE = os.sysconf("SC_PAGE_SIZE")
HZ = os.sysconf("SC_CLK_TCK")


def processes():
    """(pid, argv) of every process, argv as bytes."""
    for pid in os.listdir("/proc"):
        if not pid.isdigit():
            continue
        try:
            with open("/proc/%s/cmdline" % pid, "rb") as f:
                yield int(pid), f.read().split(b"\0")
        except OSError:
            continue


def identifier_pids(method):
    out = {}
    for pid, args in processes():
        if args and args[0].endswith(b"/identifier"):
            try:  # roslaunch passes the namespace in the environment
                with open("/proc/%d/environ" % pid, "rb") as f:
                    env = dict(e.split(b"=", 1) for e in f.read().split(b"\0") if b"=" in e)
            except OSError:
                continue
            if b"ROS_NAMESPACE" in env:
                out[pid] = env[b"ROS_NAMESPACE"].decode().rstrip("/") + "/"
    return out


def manager_pid():
    for pid, args in processes():
        if len(args) > 1 and args[0].endswith(b"/nodelet") and args[1] == b"manager" and \
                b"__name:=fleet_manager" in args:
            return pid
    return None


def cpu_rss(pid):
    with open("/proc/%d/stat" % pid) as f:
        fields = f.read().rsplit(")", 1)[1].split()
    cpu = (int(fields[11]) + int(fields[12])) / HZ  # utime + stime [s]
    rss = int(fields[21]) * PAGE / 1e6              # [MB]
    return cpu, rss


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--motors", type=int, default=8)
    p.add_argument("--duration", type=float, default=20.0)
    p.add_argument("--method", default="fbdapso")
    p.add_argument("--port", type=int, default=11611)
    p.add_argument("--processes", action="store_true", help="a process per plant and identifier, no nodelets")
    p.add_argument("--threads", type=int, default=4, help="the nodelet manager's worker threads")
    p.add_argument("--substeps", type=int, default=2, help="RK4 steps per period in each plant (fleet.launch)")
    p.add_argument("--publish-period", type=float, default=0.1,
                   help="each identifier's estimate period [s]: this script reads every estimate of every motor")
    p.add_argument("--json")
    a = p.parse_args()
    env = dict(os.environ, ROS_MASTER_URI="http://localhost:%d" % a.port)
    os.environ["ROS_MASTER_URI"] = env["ROS_MASTER_URI"]
    launch = subprocess.Popen(["roslaunch", "-p", str(a.port), "pmsm_param_id", "fleet.launch",
                               "motors:=%d" % a.motors, "duration:=%g" % a.duration, "method:=" + a.method,
                               "nodelets:=%s" % ("false" if a.processes else "true"), "threads:=%d" % a.threads,
                               "publish_period:=%g" % a.publish_period, "substeps:=%d" % a.substeps],
                              env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    time.sleep(3.0)
    import rospy
    from pmsm_param_id.msg import ParameterEstimate
    rospy.init_node("fleet_measure", anonymous=True, disable_signals=True)
    latency = {i: [] for i in range(a.motors)}
    last = {}

    def callback(i):
        def cb(msg):
            latency[i].append((rospy.Time.now() - msg.header.stamp).to_sec())
            last[i] = msg
        return cb

    for i in range(a.motors):
        rospy.Subscriber("/motor_%d/identifiers/%s/estimate" % (i, a.method), ParameterEstimate, callback(i),
                         queue_size=1000)
    samples = []  # (t, {ns: (cpu_s, rss_MB)})
    published = {}  # motor -> samples its plant published (a parameter it sets when done)
    t0 = time.time()
    while launch.poll() is None and time.time() - t0 < a.duration + 120:
        snap = {}
        pids = identifier_pids(a.method) if a.processes else {manager_pid(): "manager"}
        for pid, ns in pids.items():
            try:
                if pid is not None:
                    snap[ns] = cpu_rss(pid)
            except OSError:
                pass
        samples.append((time.time() - t0, snap))
        time.sleep(1.0)
        try:
            for i in range(a.motors):
                if rospy.has_param("/motor_%d/drive/samples_published" % i):
                    published[i] = rospy.get_param("/motor_%d/drive/samples_published" % i)
        except OSError:  # the launch (and its master) ended between the poll and this query
            break
        done = sum(1 for i in published if i in last and last[i].samples_used == published[i])
        left = max(0.0, a.duration + 3.0 - (time.time() - t0))
        sys.stderr.write("\r%d of %d motors done, about %.0f s of drive time left   " % (done, a.motors, left))
        sys.stderr.flush()
        if len(published) == a.motors and done == a.motors:
            break
    sys.stderr.write("\n")
    launch.terminate()
    launch.wait()
    own_cpu = os.times()
    own_cpu = (own_cpu.user + own_cpu.system) / max(1e-9, time.time() - t0)
    # CPU per identifier over the steady part (between the 2nd snapshot and the last), RSS first/last.
    report = {"motors": a.motors, "duration_s": a.duration, "method": a.method, "measurer_cpu_percent": 100 * own_cpu,
              "publish_period_s": a.publish_period, "substeps": a.substeps,
              "layout": "processes" if a.processes else "nodelets (%d threads)" % a.threads, "per_motor": []}

    def usage(key):
        series = [(t, s[key]) for t, s in samples if key in s]
        cpu = (series[-1][1][0] - series[0][1][0]) / (series[-1][0] - series[0][0]) if len(series) >= 2 else None
        return series, cpu

    if not a.processes:
        series, cpu = usage("manager")
        report["manager"] = {"cpu_percent": 100 * cpu if cpu is not None else None,
                             "rss_mb_first": series[0][1][1] if series else None,
                             "rss_mb_last": series[-1][1][1] if series else None}
    for i in range(a.motors):
        ns = "/motor_%d/identifiers/" % i
        series = [(t, s[ns]) for t, s in samples if ns in s]
        cpu = (series[-1][1][0] - series[1][1][0]) / (series[-1][0] - series[1][0]) if len(series) > 2 else None
        lat = latency[i]
        tail = lat[len(lat) // 2:]
        report["per_motor"].append({
            "motor": i,
            "samples_used": last[i].samples_used if i in last else 0,
            "samples_published": published.get(i),
            "latency_median_ms": 1e3 * statistics.median(lat) if lat else None,
            "latency_max_ms": 1e3 * max(lat) if lat else None,
            "latency_first_half_median_ms": 1e3 * statistics.median(lat[:len(lat) // 2]) if len(lat) > 2 else None,
            "latency_second_half_median_ms": 1e3 * statistics.median(tail) if tail else None,
            "cpu_percent": 100 * cpu if cpu is not None else None,
            "rss_mb_first": series[0][1][1] if series else None,
            "rss_mb_last": series[-1][1][1] if series else None,
        })
    print("motor  used/published   latency median/max [ms]  (1st half -> 2nd half)   CPU %   RSS MB first -> last")
    for m in report["per_motor"]:
        print("%5d  %6s/%-8s  %8.2f / %-8.2f     (%6.2f -> %6.2f)     %6.1f   %5.1f -> %5.1f" % (
            m["motor"], m["samples_used"], m["samples_published"], m["latency_median_ms"] or -1,
            m["latency_max_ms"] or -1, m["latency_first_half_median_ms"] or -1,
            m["latency_second_half_median_ms"] or -1, m["cpu_percent"] or -1, m["rss_mb_first"] or -1,
            m["rss_mb_last"] or -1))
    lat = [m["latency_median_ms"] for m in report["per_motor"] if m["latency_median_ms"] is not None]
    if lat:
        # The batching floor: an estimate is published at the first sample of a batch (the publish
        # period is one batch), which arrives when the batch's last sample is due, 99 periods later.
        periods = [last[i].sample_period for i in last if last[i].sample_period > 0]
        floor = 1e3 * 99 * statistics.median(periods) if periods else float("nan")
        report["latency_floor_ms"] = floor
        report["latency_median_of_medians_ms"] = statistics.median(lat)
        report["latency_worst_median_ms"] = max(lat)
        print("latency: median of the motors' medians %.2f ms, worst motor's median %.2f ms; batching floor %.2f ms" % (
            report["latency_median_of_medians_ms"], report["latency_worst_median_ms"], floor))
    if "manager" in report and report["manager"]["cpu_percent"] is not None:
        m = report["manager"]
        print("nodelet manager (every plant and identifier): CPU %.0f %%, RSS %.0f -> %.0f MB" % (
            m["cpu_percent"], m["rss_mb_first"], m["rss_mb_last"]))
    print("this script (reading every estimate): CPU %.0f %%" % (100 * own_cpu))
    if a.json:
        with open(a.json, "w") as f:
            json.dump(report, f, indent=1)
    ok = all(m["samples_used"] == m["samples_published"] for m in report["per_motor"])
    print("all identifiers processed every published sample: %s" % ("yes" if ok else "NO"))
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
