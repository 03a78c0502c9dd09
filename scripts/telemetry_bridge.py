#!/usr/bin/env python3
"""Any drive's telemetry message to the identifier's input (doc/ros.md, "Telemetry").

Subscribes to ~topic whatever its message type (rospy.AnyMsg: the type is read from the
connection and its Python class loaded then, so this package does not compile against the drive's
message package), takes u_d, u_q, i_d, i_q, the speed and optionally the DC bus from the field
paths in ~fields, converts the speed to electrical rad/s, and publishes one
pmsm_param_id/DriveSample per message on `samples` (the identifier with ~input: single; it takes a
stream sampled slower than 2 ms as telemetry, the steady-state fit).

Parameters:
  ~topic        the drive's topic (default: sensors/core, vesc_driver's VescStateStamped)
  ~fields       {u_d, u_q, i_d, i_q, omega_e[, v_dc][, stamp]}: field paths ('state.avg_vd',
                'values[2]'); stamp defaults to header.stamp, 'receipt' takes the arrival time.
                Default: vesc_msgs/VescStateStamped's (state.avg_vd, state.avg_vq, state.avg_id,
                state.avg_iq, state.speed, state.voltage_input)
  ~speed_unit   erpm (default) | rad/s (electrical) | hz (electrical) | rpm | mech_rad/s
                (the last two mechanical: need ~pole_pairs)
  ~pole_pairs   int, where the speed unit is mechanical
Every unit's factor is the one the CSV reader uses (LogFormat::speedFactor in src/core/io/log_format.cpp).
"""
import math
import sys

import genpy
import roslib.message
import rospy

from pmsm_param_id.msg import DriveSample

VESC_FIELDS = {
    'u_d': 'state.avg_vd',
    'u_q': 'state.avg_vq',
    'i_d': 'state.avg_id',
    'i_q': 'state.avg_iq',
    'omega_e': 'state.speed',
    'v_dc': 'state.voltage_input',
    'stamp': 'header.stamp',
}
REQUIRED = ('u_d', 'u_q', 'i_d', 'i_q', 'omega_e')
OPTIONAL = ('v_dc', 'stamp')
# Electrical rad/s per unit; the mechanical ones are multiplied by the pole pairs.
SPEED_UNITS = {'rad/s': (1.0, False), 'hz': (2.0 * math.pi, False), 'erpm': (2.0 * math.pi / 60.0, False),
               'rpm': (2.0 * math.pi / 60.0, True), 'mech_rad/s': (1.0, True)}


def parse_path(path):
    """'state.values[2].x' -> ['state', 'values', 2, 'x']; ValueError naming the path."""
    parts = []
    for token in path.split('.'):
        name, _, rest = token.partition('[')
        if not name.isidentifier():
            raise ValueError("field path '%s': '%s' is not a field name" % (path, name))
        parts.append(name)
        while rest:
            index, _, rest = rest.partition(']')
            if not index.isdigit():
                raise ValueError("field path '%s': index '%s' is not a number" % (path, index))
            parts.append(int(index))
            rest = rest[1:] if rest.startswith('[') else rest
            if rest:
                raise ValueError("field path '%s': unexpected '%s'" % (path, rest))
    return parts


def resolve(msg, parts):
    value = msg
    for p in parts:
        value = value[p] if isinstance(p, int) else getattr(value, p)
    return value


class Bridge:
    def __init__(self):
        self.topic = rospy.get_param('~topic', 'sensors/core')
        fields = rospy.get_param('~fields', VESC_FIELDS)
        if not isinstance(fields, dict):
            raise ValueError('~fields: expected a dictionary {u_d: path, ...}, got %r' % (fields,))
        unknown = sorted(set(fields) - set(REQUIRED) - set(OPTIONAL))
        if unknown:
            raise ValueError('~fields: unknown key(s) %s (expected %s)' % (', '.join(unknown),
                                                                           ', '.join(REQUIRED + OPTIONAL)))
        missing = [k for k in REQUIRED if k not in fields]
        if missing:
            raise ValueError('~fields: missing %s' % ', '.join(missing))
        self.paths = {k: parse_path(str(v)) for k, v in fields.items() if k != 'stamp'}
        stamp = str(fields.get('stamp', 'header.stamp'))
        self.stamp_path = None if stamp == 'receipt' else parse_path(stamp)
        unit = rospy.get_param('~speed_unit', 'erpm')
        if unit not in SPEED_UNITS:
            raise ValueError("~speed_unit: '%s' is not one of %s" % (unit, ', '.join(SPEED_UNITS)))
        factor, mechanical = SPEED_UNITS[unit]
        if mechanical:
            pole_pairs = rospy.get_param('~pole_pairs', 0)
            if not isinstance(pole_pairs, int) or pole_pairs <= 0:
                raise ValueError('~speed_unit %s is a mechanical speed: set ~pole_pairs (a positive integer)' % unit)
            factor *= pole_pairs
        self.speed_factor = factor
        self.msg_class = None
        self.bad = 0
        self.forwarded = 0
        self.pub = rospy.Publisher('samples', DriveSample, queue_size=10000)
        self.sub = rospy.Subscriber(self.topic, rospy.AnyMsg, self.on_message, queue_size=10000)
        rospy.loginfo('telemetry bridge: %s -> %s (speed in %s)', self.sub.resolved_name, self.pub.resolved_name, unit)

    def on_message(self, raw):
        if self.msg_class is None:
            type_name = raw._connection_header.get('type', '')
            self.msg_class = roslib.message.get_message_class(type_name)
            if self.msg_class is None:
                rospy.logerr_throttle(10.0, "telemetry bridge: message type '%s' on %s has no Python class here "
                                      "(source its workspace's setup.bash)" % (type_name, self.topic))
                return
            rospy.loginfo('telemetry bridge: %s carries %s', self.topic, type_name)
        try:
            msg = self.msg_class().deserialize(raw._buff)
            values = {k: float(resolve(msg, p)) for k, p in self.paths.items()}
            stamp = rospy.get_rostime() if self.stamp_path is None else resolve(msg, self.stamp_path)
            if not isinstance(stamp, genpy.Time):
                raise TypeError('the stamp field is not a time')
        except (AttributeError, IndexError, TypeError, ValueError, genpy.DeserializationError) as e:
            self.bad += 1
            rospy.logwarn_throttle(1.0, 'telemetry bridge: a message dropped (%s; %d so far)' % (e, self.bad))
            return
        out = DriveSample()
        out.header.stamp = stamp
        out.u_d, out.u_q = values['u_d'], values['u_q']
        out.i_d, out.i_q = values['i_d'], values['i_q']
        out.omega_e = values['omega_e'] * self.speed_factor
        out.theta_e = float('nan')  # telemetry carries no angle
        out.v_dc = values.get('v_dc', float('nan'))
        self.pub.publish(out)
        self.forwarded += 1


def main():
    rospy.init_node('telemetry_bridge')
    try:
        Bridge()
    except ValueError as e:
        rospy.logfatal('telemetry bridge: %s' % e)
        sys.exit(2)
    rospy.spin()


if __name__ == '__main__':
    main()
