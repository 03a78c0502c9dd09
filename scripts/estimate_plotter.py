#!/usr/bin/env python3
"""estimate_plotter node: live time-series plots of the estimates for rviz.

rviz has no time-series display; this node draws one as a visualization_msgs/MarkerArray of
LINE_STRIPs (x = time, y = value) with axes, tick labels, a legend and the current value and error,
in the fixed frame "plot" (no TF needed), for rviz/monitor.rviz's top-down orthographic view.
Beside the fitness: the winding and magnet temperatures (thick: winding, thin: magnet; black:
truth) when the identifiers carry them (a thermal: block), and the condition monitor's alarms
(~namespace/METHOD/events): every active alarm in red, or "no alarm active", and below them the
latest five raises and clears (grey), newest first.

Parameters:
  ~methods (list of str)   methods to draw (default fbdapso, sapso, pso, ekf, rls)
  ~namespace (str)         where the identifiers live (default /identifiers)
  ~truth_topic (str)       ElectricalParameters topic (default /drive/true_parameters)
  ~window (double, s)      time span shown, stamp time (default 1.0)
  ~rate (double, Hz)       redraw rate (default 5)
  ~frame_id (str)          default "plot"
Publishes ~markers (visualization_msgs/MarkerArray).
"""
import math
import threading
from collections import deque

STATUS_CONSTANTS = ("NO_DATA", "IDENTIFIED", "NOT_EXCITED", "POOR_FIT", "AT_BOUND", "IMPLAUSIBLE", "NOT_CONVERGED")


def report_status_names(msg):
    """Per-parameter status names from the codes, named by ParameterEstimate.msg's own constants."""
    names = {getattr(type(msg), c, i): c.lower() for i, c in enumerate(STATUS_CONSTANTS)}
    codes = list(getattr(msg, "status", []) or [])
    return [names.get(c, "status %d" % c) for c in codes] if len(codes) == 4 else None

PARAMS = ["R_s", "L_d", "L_q", "psi_f"]
UNITS = {"R_s": "ohm", "L_d": "H", "L_q": "H", "psi_f": "Wb"}
METHODS = ["fbdapso", "sapso", "pso", "ekf", "rls"]
COLORS = {"fbdapso": (0.84, 0.15, 0.16), "sapso": (1.0, 0.5, 0.05), "pso": (0.17, 0.63, 0.17),
          "ekf": (0.12, 0.47, 0.71), "rls": (0.58, 0.4, 0.74), "truth": (0.0, 0.0, 0.0)}
GREY = (0.6, 0.6, 0.6)
PANEL_W, PANEL_H = 10.0, 4.0
# panel origins (lower-left corners): 2 x 2 parameters, fitness below
ORIGINS = {"R_s": (0.0, 11.0), "L_d": (17.0, 11.0), "L_q": (0.0, 5.5), "psi_f": (17.0, 5.5), "fitness": (0.0, 0.0),
           "temperature": (17.0, 0.0)}
ALARM_RED = (0.85, 0.0, 0.0)
OK_GREEN = (0.0, 0.5, 0.0)
MAX_POINTS = 250   # per line strip: software-GL rviz falls behind on ~20k points per redraw
LEGEND_SIZE = 0.3  # text height; TEXT_VIEW_FACING is centred, so legends are placed by half their width


class PlotState:
    """Sliding window of estimates per method and of the truth (pure Python, no ROS)."""

    def __init__(self, window=1.0, methods=METHODS):
        self.window = window
        self.methods = list(methods)
        self.series = {m: deque() for m in self.methods}  # (t, values, identifiable, fitness)
        self.truth = deque()                                 # (t, values)
        self.status = {}                                     # method: latest status names
        self.temperatures = {m: deque() for m in self.methods}  # (t, winding, magnet) [degC], NaN = unknown
        self.truth_temperatures = deque()                    # (t, winding, magnet) [degC]
        self.active_alarms = {}                              # (method, kind): (t, text)
        self.alarm_log = deque(maxlen=5)                     # the latest raises and clears, newest last

    def add_estimate(self, method, t, values, identifiable, fitness, status=None, temperatures=None):
        if method not in self.series:
            return
        if status is not None:
            self.status[method] = list(status)
        s = self.series[method]
        if s and t < s[-1][0]:  # stamps went backwards (bag loop): start over
            s.clear()
            self.temperatures[method].clear()
            self.active_alarms = {k: v for k, v in self.active_alarms.items() if k[0] != method}
        s.append((t, tuple(values), tuple(identifiable), fitness))
        self._trim(s, t)
        if temperatures is not None:
            self.temperatures[method].append((t,) + tuple(temperatures))
            self._trim(self.temperatures[method], t)

    def add_truth(self, t, values, temperatures=None):
        if self.truth and t < self.truth[-1][0]:
            self.truth.clear()
            self.truth_temperatures.clear()
        self.truth.append((t, tuple(values)))
        self._trim(self.truth, t)
        if temperatures is not None:
            self.truth_temperatures.append((t,) + tuple(temperatures))
            self._trim(self.truth_temperatures, t)

    def add_event(self, t, method, kind, raised, text):
        """An alarm raised or cleared by a condition monitor (ConditionEvent)."""
        if raised:
            self.active_alarms[(method, kind)] = (t, text)
        else:
            self.active_alarms.pop((method, kind), None)
        self.alarm_log.append((t, method, kind, raised))

    def _trim(self, q, now):
        while len(q) > 2 and q[0][0] < now - self.window:
            q.popleft()

    def latest_time(self):
        times = [s[-1][0] for s in self.series.values() if s] + ([self.truth[-1][0]] if self.truth else [])
        return max(times) if times else None


def nice_ticks(lo, hi, n=4):
    """Round tick values covering [lo, hi]."""
    if not (math.isfinite(lo) and math.isfinite(hi)) or hi <= lo:
        return [lo]
    raw = (hi - lo) / n
    mag = 10 ** math.floor(math.log10(raw))
    step = min((m * mag for m in (1, 2, 2.5, 5, 10) if m * mag >= raw), default=raw)
    first = math.ceil(lo / step) * step
    return [first + k * step for k in range(int((hi - first) / step + 1e-9) + 1)]


def thin(seq, max_points=MAX_POINTS):
    """Every k-th element so that at most max_points remain, always keeping the newest."""
    seq = list(seq)
    if len(seq) <= max_points:
        return seq
    step = math.ceil(len(seq) / (max_points - 1))
    out = seq[-1::-step][::-1]
    return out


def value_range(state, i):
    """y range of panel i: truth +-20 % when known, else the data's span (+10 %)."""
    if state.truth:
        ref = state.truth[-1][1][i]
        return ref * 0.8, ref * 1.2
    vals = [v[i] for s in state.series.values() for _, v, _, _ in s if math.isfinite(v[i])]
    if not vals:
        return 0.0, 1.0
    lo, hi = min(vals), max(vals)
    pad = 0.1 * (hi - lo) if hi > lo else 0.1 * abs(hi) + 1e-12
    return lo - pad, hi + pad


def build_markers(state, frame_id="plot", stamp=None):
    """MarkerArray for the current state. Returns (MarkerArray, layout) where layout maps each
    panel to its (t0, t1, y0, y1) data span, for tests."""
    from geometry_msgs.msg import Point
    from std_msgs.msg import ColorRGBA
    from visualization_msgs.msg import Marker, MarkerArray

    arr = MarkerArray()
    layout = {}
    now = state.latest_time()
    if now is None:
        return arr, layout
    t0, t1 = now - state.window, now
    mid = [0]

    def marker(ns, mtype, scale=0.04, color=(0, 0, 0)):
        m = Marker()
        m.header.frame_id = frame_id
        if stamp is not None:
            m.header.stamp = stamp
        m.ns = ns
        m.id = mid[0]
        mid[0] += 1
        m.type = mtype
        m.action = Marker.ADD
        m.pose.orientation.w = 1.0
        m.scale.x = m.scale.y = m.scale.z = scale
        m.color.r, m.color.g, m.color.b = color
        m.color.a = 1.0
        return m

    def text(ns, x, y, s, size=0.35, color=(0, 0, 0)):
        m = marker(ns, Marker.TEXT_VIEW_FACING, size, color)
        m.pose.position.x, m.pose.position.y = x, y
        m.text = s
        arr.markers.append(m)

    def panel(name, ox, oy, y0, y1, ylabel, fmt_tick, is_log=False):
        layout[name] = (t0, t1, y0, y1)
        box = marker(name + "/axes", Marker.LINE_STRIP, 0.03)
        for x, y in ((0, 0), (PANEL_W, 0), (PANEL_W, PANEL_H), (0, PANEL_H), (0, 0)):
            box.points.append(Point(ox + x, oy + y, 0))
        arr.markers.append(box)
        ticks = marker(name + "/ticks", Marker.LINE_LIST, 0.02)
        for v in (range(int(math.ceil(y0)), int(math.floor(y1)) + 1) if is_log else nice_ticks(y0, y1)):
            y = oy + (v - y0) / (y1 - y0) * PANEL_H
            ticks.points += [Point(ox - 0.15, y, 0), Point(ox, y, 0)]
            text(name + "/ticklabels", ox - 0.9, y, fmt_tick(v), 0.28)
        for k in range(5):
            x = ox + k / 4 * PANEL_W
            ticks.points += [Point(x, oy - 0.15, 0), Point(x, oy, 0)]
            text(name + "/ticklabels", x, oy - 0.45, "%.2f" % (t0 + k / 4 * (t1 - t0)), 0.28)
        arr.markers.append(ticks)
        text(name + "/title", ox + PANEL_W / 2, oy + PANEL_H + 0.4, ylabel + "   (time [s])", 0.4)

    def xy(ox, oy, t, v, y0, y1):
        y = min(max((v - y0) / (y1 - y0), -0.05), 1.05)
        return Point(ox + (t - t0) / (t1 - t0) * PANEL_W, oy + y * PANEL_H, 0)

    for i, p in enumerate(PARAMS):
        ox, oy = ORIGINS[p]
        y0, y1 = value_range(state, i)
        panel(p, ox, oy, y0, y1, "%s [%s]" % (p, UNITS[p]), lambda v: "%.4g" % v)
        if state.truth:
            strip = marker(p + "/truth", Marker.LINE_STRIP, 0.06, COLORS["truth"])
            for t, v in thin(state.truth):
                strip.points.append(xy(ox, oy, max(t, t0), v[i], y0, y1))
            strip.points.append(xy(ox, oy, t1, state.truth[-1][1][i], y0, y1))
            arr.markers.append(strip)
        row = 0
        for m in state.methods:
            s = state.series[m]
            if not s:
                continue
            strip = marker(p + "/" + m, Marker.LINE_STRIP, 0.04, COLORS.get(m, (0, 0, 0)))
            for t, v, ok, _ in thin(s):
                if math.isfinite(v[i]):
                    strip.points.append(xy(ox, oy, t, v[i], y0, y1))
                    c = COLORS.get(m, (0, 0, 0)) if ok[i] else GREY  # grey: not identifiable
                    strip.colors.append(ColorRGBA(c[0], c[1], c[2], 1.0))
            if len(strip.points) >= 2:
                arr.markers.append(strip)
            _, v, ok, _ = s[-1]
            label = "%s %.5g" % (m, v[i])
            if state.truth:
                label += " (%+.2f %%)" % (100.0 * (v[i] / state.truth[-1][1][i] - 1.0))
            if not ok[i]:
                label += " " + (state.status[m][i] if m in state.status else "not identified")
            text(p + "/legend", ox + PANEL_W + 0.3 + 0.5 * 0.6 * LEGEND_SIZE * len(label),
                 oy + PANEL_H - 0.35 - 0.5 * row, label, LEGEND_SIZE, COLORS.get(m, (0, 0, 0)) if ok[i] else GREY)
            row += 1
    # fitness, log10 scale, swarm methods only (ekf and rls have no swarm fitness of their own)
    ox, oy = ORIGINS["fitness"]
    logs = [math.log10(f) for m in ("fbdapso", "sapso", "pso") if m in state.series
            for _, _, _, f in state.series[m] if f > 0 and math.isfinite(f)]
    y0, y1 = (math.floor(min(logs)), math.ceil(max(logs)) + (1 if min(logs) == max(logs) else 0)) if logs else (-4, 0)
    if y1 <= y0:
        y1 = y0 + 1
    panel("fitness", ox, oy, y0, y1, "fitness [A^2] (log10)", lambda v: "%g" % 10 ** v, True)
    for m in ("fbdapso", "sapso", "pso"):
        s = state.series.get(m)
        if not s:
            continue
        strip = marker("fitness/" + m, Marker.LINE_STRIP, 0.04, COLORS[m])
        for t, _, _, f in thin(s):
            if f > 0 and math.isfinite(f):
                strip.points.append(xy(ox, oy, t, math.log10(f), y0, y1))
        if len(strip.points) >= 2:
            arr.markers.append(strip)
    draw_monitor(state, panel, marker, text, xy, arr)
    return arr, layout


def finite(x):
    return isinstance(x, float) and math.isfinite(x)


def draw_monitor(state, panel, marker, text, xy, arr):
    """Temperatures (when any is known) and the active alarms, right of the fitness panel."""
    from visualization_msgs.msg import Marker
    ox, oy = ORIGINS["temperature"]
    series = [(m, state.temperatures[m]) for m in state.methods if state.temperatures.get(m)]
    known = [v for _, q in series for _, w, mg in q for v in (w, mg) if finite(v)]
    known += [v for _, w, mg in state.truth_temperatures for v in (w, mg) if finite(v)]
    legend_row = 0
    if known:
        lo, hi = min(known), max(known)
        y0, y1 = lo - 5.0 - 0.05 * (hi - lo), hi + 5.0 + 0.05 * (hi - lo)
        panel("temperature", ox, oy, y0, y1, "temperature [degC] (thick: winding, thin: magnet)", lambda v: "%.0f" % v)
        lines = [("truth", state.truth_temperatures, COLORS["truth"])] + [(m, q, COLORS.get(m, (0, 0, 0))) for m, q in series]
        for name, q, color in lines:
            for k, (part, width) in enumerate((("winding", 0.07), ("magnet", 0.03))):
                strip = marker("temperature/%s/%s" % (name, part), Marker.LINE_STRIP, width, color)
                for point in thin(q):
                    if finite(point[1 + k]):
                        strip.points.append(xy(ox, oy, point[0], point[1 + k], y0, y1))
                if len(strip.points) >= 2:
                    arr.markers.append(strip)
        for name, q, color in lines:
            if not q:
                continue
            w, mg = q[-1][1], q[-1][2]
            label = "%s winding %s, magnet %s degC" % (name, "%.1f" % w if finite(w) else "n/a", "%.1f" % mg if finite(mg) else "n/a")
            text("temperature/legend", ox + PANEL_W + 0.3 + 0.5 * 0.6 * LEGEND_SIZE * len(label),
                 oy + PANEL_H - 0.35 - 0.5 * legend_row, label, LEGEND_SIZE, color)
            legend_row += 1
    alarms = sorted(state.active_alarms.items(), key=lambda kv: kv[1][0])
    labels = ["ALARM %s %s at %.2f s: %s" % (m, kind, t, msg) for (m, kind), (t, msg) in alarms] or ["no alarm active"]
    for label in labels[:6]:
        text("alarms", ox + PANEL_W + 0.3 + 0.5 * 0.6 * LEGEND_SIZE * len(label), oy + PANEL_H - 0.35 - 0.5 * legend_row,
             label, LEGEND_SIZE, ALARM_RED if alarms else OK_GREEN)
        legend_row += 1
    # the timeline: the latest raises and clears, newest first
    for t, m, kind, raised in reversed(state.alarm_log):
        label = "%.2f s %s %s %s" % (t, m, kind, "raised" if raised else "cleared")
        text("alarm_log", ox + PANEL_W + 0.3 + 0.5 * 0.6 * LEGEND_SIZE * len(label), oy + PANEL_H - 0.35 - 0.5 * legend_row,
             label, LEGEND_SIZE, GREY)
        legend_row += 1


def main():
    import rospy
    from pmsm_param_id.msg import ConditionEvent, ElectricalParameters, ParameterEstimate
    from visualization_msgs.msg import MarkerArray

    rospy.init_node("estimate_plotter")
    methods = rospy.get_param("~methods", METHODS)
    ns = rospy.get_param("~namespace", "/identifiers").rstrip("/")
    frame = rospy.get_param("~frame_id", "plot")
    rate = float(rospy.get_param("~rate", 5.0))
    window = float(rospy.get_param("~window", 1.0))
    if window <= 0 or rate <= 0:
        rospy.logfatal("parameters ~window and ~rate must be > 0")
        return 1
    state = PlotState(window, methods)
    origin = []
    # The subscribers' callbacks run on rospy's threads and the drawing on this one: one lock, or a
    # deque changes while the markers iterate over it.
    lock = threading.Lock()

    def seconds(stamp):
        if not origin or stamp.to_nsec() < origin[0]:
            origin[:] = [stamp.to_nsec()]
        return (stamp.to_nsec() - origin[0]) * 1e-9

    def on_estimate(msg):
        with lock:
            state.add_estimate(msg.method, seconds(msg.header.stamp), (msg.R_s, msg.L_d, msg.L_q, msg.psi_f),
                               msg.identifiable, msg.fitness, report_status_names(msg),
                               (msg.winding_temperature, msg.magnet_temperature))

    def on_truth(msg):
        with lock:
            state.add_truth(seconds(msg.header.stamp), (msg.R_s, msg.L_d, msg.L_q, msg.psi_f),
                            (msg.winding_temperature, msg.magnet_temperature))

    def on_event(msg):
        with lock:
            state.add_event(seconds(msg.header.stamp), msg.method, msg.kind, msg.raised, msg.text)

    for m in methods:
        rospy.Subscriber("%s/%s/estimate" % (ns, m), ParameterEstimate, on_estimate, queue_size=1000)
        rospy.Subscriber("%s/%s/events" % (ns, m), ConditionEvent, on_event, queue_size=100)
    rospy.Subscriber(rospy.get_param("~truth_topic", "/drive/true_parameters"), ElectricalParameters, on_truth,
                     queue_size=1000)
    from visualization_msgs.msg import Marker
    pub = rospy.Publisher("~markers", MarkerArray, queue_size=2)
    r = rospy.Rate(rate)
    while not rospy.is_shutdown():
        with lock:
            arr, _ = build_markers(state, frame)
        if arr.markers:
            clear = Marker()  # first in the same array: rviz drops the old plot and draws the new one at once
            clear.action = Marker.DELETEALL
            clear.header.frame_id = frame
            arr.markers.insert(0, clear)
            pub.publish(arr)
        try:
            r.sleep()
        except rospy.ROSInterruptException:
            break
    return 0


if __name__ == "__main__":
    import sys
    sys.exit(main())
