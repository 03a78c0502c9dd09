#!/usr/bin/env python3
"""Runs `rosbag play ARGS` once the identifiers listen, then stays up until they have drained.

Used as the required node of replay.launch: the launch ends when the bag has been played and the
identifiers have processed the last samples and published their final estimates. With --wait-topic
the player stays up until none of those topics has had a message for --linger seconds (at most
--max-linger): a fixed wait lost an identifier's last estimates when the machine was busy.
Without it, it stays up --linger seconds.
"""
import argparse
import subprocess
import sys
import time

import rosgraph
import rospy


def subscribers(master, topic):
    _, subs, _ = master.getSystemState()
    for name, nodes in subs:
        if name == topic:
            return len(nodes)
    return 0


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--linger", type=float, default=2.0,
                        help="seconds of silence on the --wait-topic topics (or, without them, seconds) "
                             "to stay up after the bag [s]")
    parser.add_argument("--max-linger", type=float, default=60.0,
                        help="stay up at most this long after the bag, whatever arrives [s]")
    parser.add_argument("--wait-subscribers", type=int, default=0,
                        help="wait (at most 20 s) for this many subscribers of /drive/samples_batch")
    parser.add_argument("--wait-topic", action="append", default=[],
                        help="also wait (same limit) until this topic has a subscriber, e.g. a recorder's")
    parser.add_argument("play_args", nargs=argparse.REMAINDER)
    args, _ = parser.parse_known_args(rospy_argv_filter(sys.argv[1:]))
    play_args = [a for a in args.play_args if a != "--"]
    master = rosgraph.Master("/play_and_linger")
    last_message = [time.time()]
    if args.wait_topic:
        rospy.init_node("player", disable_signals=True)

        def seen(_):
            last_message[0] = time.time()

        for topic in args.wait_topic:
            rospy.Subscriber(topic, rospy.AnyMsg, seen)
    deadline = time.time() + 20.0
    while time.time() < deadline:
        if subscribers(master, "/drive/samples_batch") >= args.wait_subscribers and all(
                subscribers(master, t) > 0 for t in args.wait_topic):
            break
        time.sleep(0.1)
    time.sleep(1.0)
    # -d: wait after advertising, so every subscriber is connected before the first message.
    code = subprocess.call(["rosbag", "play", "-d", "1"] + play_args)
    played = time.time()
    last_message[0] = max(last_message[0], played)
    if not args.wait_topic:
        time.sleep(args.linger)
        return code
    while time.time() - last_message[0] < args.linger and time.time() - played < args.max_linger:
        time.sleep(0.1)
    if time.time() - played >= args.max_linger:
        print("play_and_linger: estimates still arriving %.0f s after the bag ended; stopping anyway"
              % args.max_linger, file=sys.stderr)
    return code


def rospy_argv_filter(argv):
    # roslaunch appends __name:= and __log:= arguments.
    return [a for a in argv if not a.startswith("__")]


if __name__ == "__main__":
    sys.exit(main())
