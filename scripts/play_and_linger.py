#!/usr/bin/env python3
"""Runs `rosbag play ARGS` once the identifiers listen, then stays up --linger seconds.

Used as the required node of replay.launch: the launch ends when the bag has been played and the
identifiers have had time to process the last samples and publish their final estimates.
"""
import argparse
import subprocess
import sys
import time

import rosgraph


def subscribers(master, topic):
    _, subs, _ = master.getSystemState()
    for name, nodes in subs:
        if name == topic:
            return len(nodes)
    return 0


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--linger", type=float, default=2.0, help="seconds to stay up after the bag [s]")
    parser.add_argument("--wait-subscribers", type=int, default=0,
                        help="wait (at most 20 s) for this many subscribers of /drive/samples_batch")
    parser.add_argument("--wait-topic", action="append", default=[],
                        help="also wait (same limit) until this topic has a subscriber, e.g. a recorder's")
    parser.add_argument("play_args", nargs=argparse.REMAINDER)
    args, _ = parser.parse_known_args(rospy_argv_filter(sys.argv[1:]))
    play_args = [a for a in args.play_args if a != "--"]
    master = rosgraph.Master("/play_and_linger")
    deadline = time.time() + 20.0
    while time.time() < deadline:
        if subscribers(master, "/drive/samples_batch") >= args.wait_subscribers and all(
                subscribers(master, t) > 0 for t in args.wait_topic):
            break
        time.sleep(0.1)
    time.sleep(1.0)
    # -d: wait after advertising, so every subscriber is connected before the first message.
    code = subprocess.call(["rosbag", "play", "-d", "1"] + play_args)
    time.sleep(args.linger)
    return code


def rospy_argv_filter(argv):
    # roslaunch appends __name:= and __log:= arguments.
    return [a for a in argv if not a.startswith("__")]


if __name__ == "__main__":
    sys.exit(main())
