#!/usr/bin/env python3
"""Runs `rosbag play ARGS` once the identifiers listen, then stays up until they have drained.

Used as the required node of replay.launch: the launch ends when the bag has been played and the
identifiers have processed the last samples and published their final estimates. With --wait-topic
the player stays up until none of those topics has had a message for --linger seconds (at most
--max-linger): a fixed wait lost an identifier's last estimates when the machine was busy.
Without it, it stays up --linger seconds.

The bag starts paused and is resumed only when every subscriber the master lists for what it plays
(samples, truth, clock) and for each --wait-topic is connected, as the nodes' own bus information
says: a subscriber the master already lists can still be connecting. On a loaded machine two
identifiers lost the first 300 samples that way (their estimates then differed from the live run's
all along), and a recorder whose clock was not yet connected lost the first half of the estimates.
"""
import argparse
import os
import subprocess
import sys
import time
import xmlrpc.client

import rosgraph
import rospy


def subscribers_by_topic(master):
    """Every topic's subscribing nodes, as the master lists them (one query)."""
    _, subs, _ = master.getSystemState()
    return {name: nodes for name, nodes in subs}


def connected(master, node, topic, direction):
    """Connections of `node` on `topic` in `direction` ('i' in, 'o' out) that its bus info reports up."""
    try:
        _, _, bus = xmlrpc.client.ServerProxy(master.lookupNode(node)).getBusInfo("/player")
    except Exception:  # the node is gone or not answering yet: not connected
        return 0
    return sum(1 for c in bus if c[4] == topic and c[2] == direction and (len(c) <= 5 or c[5]))


# What the bag player publishes: the samples, the truth and, under simulated time, the clock (a
# recorder whose clock is not yet connected stamps what it receives with time 0 and cannot write it).
PLAYED_TOPICS = ("/drive/samples_batch", "/drive/true_parameters", "/clock")


def wait_connected(master, play, player, topics, timeout):
    """True once the bag player has a connection to every listed subscriber of what it plays and
    every listed subscriber of each topic has its inbound connection up; False after the timeout or
    when the player has exited (a bag that cannot be read)."""
    deadline = time.time() + timeout
    while time.time() < deadline and play.poll() is None:
        subs = subscribers_by_topic(master)
        ready = all(connected(master, player, t, "o") >= len(subs.get(t, [])) for t in PLAYED_TOPICS)
        ready = ready and all(connected(master, n, t, "i") >= 1 for t in topics for n in subs.get(t, []))
        if ready:
            return True
        time.sleep(0.1)
    return False


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
        subs = subscribers_by_topic(master)
        if len(subs.get("/drive/samples_batch", [])) >= args.wait_subscribers and all(
                subs.get(t) for t in args.wait_topic):
            break
        time.sleep(0.1)
    # The bag starts paused; it is resumed once every subscriber is connected (at most 30 s).
    player = "/bag_player_%d" % os.getpid()
    play = subprocess.Popen(["rosbag", "play", "--pause"] + play_args + ["__name:=" + player.lstrip("/")])
    started = time.time()
    if wait_connected(master, play, player, args.wait_topic, 30.0):
        print("play_and_linger: %d subscribers of the samples connected after %.1f s; playing" % (
            connected(master, player, "/drive/samples_batch", "o"), time.time() - started))
    elif play.poll() is not None:
        print("play_and_linger: rosbag play exited with code %d before playing" % play.returncode, file=sys.stderr)
        return play.returncode or 1
    else:
        print("play_and_linger: not every subscriber connected within 30 s; playing anyway", file=sys.stderr)
    try:
        from std_srvs.srv import SetBool
        rospy.wait_for_service(player + "/pause_playback", timeout=30.0)
        rospy.ServiceProxy(player + "/pause_playback", SetBool)(False)
    except Exception as e:  # a rosbag without the service (before 1.15): stop, saying why
        print("play_and_linger: could not resume the bag through %s/pause_playback (%s)" % (player, e),
              file=sys.stderr)
        play.kill()
        return 1
    code = play.wait()
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
