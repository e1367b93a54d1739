#!/usr/bin/env python3
"""An example robot driving zonemapd over its line protocol (Python 3, standard library only).

It plays a simulated scenario (zonemap sim ...) as if its own camera and odometry produced it:
it starts zonemapd, sends its planned path as a `route` line (the ground-truth path, 1 waypoint
a metre, as a navigation stack would plan it), streams every frame, pulls the memory lever
halfway (`budget` down to half of K_max, as a supervisor would when the VLM needs memory
back) and later gives it back, and reads one pose line per frame: the corrected pose, the
map<-odom correction, the covariance, the status. With --check it verifies what a robot relies
on and exits non-zero when something is off; it always prints a summary, including how well
the covariance describes the true error (the scenario's ground truth).

    examples/robot/robot.py --zonemapd build/host-release/app/zonemapd --scenario DIR
    examples/robot/robot.py ... --transport udp          # datagrams instead of stdin/stdout
    examples/robot/robot.py ... --emulator "qemu-aarch64 -L /opt/zonemap/sysroot-arm64"

A ROS 2 node would do the same with nav_msgs/Odometry + image features in, and publish each pose
line as geometry_msgs/PoseWithCovarianceStamped plus the map->odom transform (README).
"""

import argparse
import math
import os
import shlex
import socket
import subprocess
import sys
import tempfile
import threading

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import zonemap_protocol as zp  # noqa: E402

UDP_PAYLOAD_MAX = 65507


def qmul(a, b):
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz)


def qrot(q, v):
    x, y, z = qmul(qmul(q, (v[0], v[1], v[2], 0.0)), (-q[0], -q[1], -q[2], q[3]))[:3]
    return (x, y, z)


def compose(p_a, q_a, p_b, q_b):
    """(p_a, q_a) * (p_b, q_b)."""
    r = qrot(q_a, p_b)
    return (p_a[0] + r[0], p_a[1] + r[1], p_a[2] + r[2]), qmul(q_a, q_b)


class Robot:
    def __init__(self, args):
        self.args = args
        self.failures = []
        self.poses = []
        self.acks = []
        self.hello = None
        self.sent_odom = {}

    def fail(self, what):
        self.failures.append(what)
        print("robot: CHECK FAILED: " + what, file=sys.stderr)

    def command(self, transport_args, out_dir):
        a = self.args
        cmd = shlex.split(a.emulator) if a.emulator else []
        cmd += [a.zonemapd, "--profile", a.profile, "--db", os.path.join(a.scenario, "map.db"),
                "--out", out_dir, "--max-features", str(a.max_features)] + transport_args
        if a.memory_thr:
            cmd += ["--memory-thr", a.memory_thr]
        if a.policy:
            cmd += ["--policy", a.policy]
        return cmd

    def frames(self):
        frames = zp.FramesFile(os.path.join(self.args.scenario, "frames.bin"))
        blind = []
        for r in filter(None, self.args.blind.split(",")):
            start, count = (int(x) for x in r.split(":"))
            blind.append((start, start + count))
        for i, (stamp, pos, quat, feats) in enumerate(frames):
            if self.args.frames and i >= self.args.frames:
                break
            if any(a <= i < b for a, b in blind):
                feats = []  # the camera is blind: odometry only, dead reckoning
            yield stamp, pos, quat, feats
        frames.close()

    def plan(self):
        """The control lines to send before which frame index: route first, budget lever."""
        gt_path = os.path.join(self.args.scenario, "localization_gt.tum")
        n = self.args.frames or zp.FramesFile(os.path.join(self.args.scenario, "frames.bin")).count
        lines = {}
        if os.path.exists(gt_path):
            limit = int(self.hello.get("max_route_waypoints", 4096))
            lines.setdefault(0, []).append(zp.format_route(zp.route_from_truth(zp.read_tum(gt_path),
                                                                             limit=limit)))
        k_max = int(self.hello["k_max"])
        if n >= 6 and k_max >= 2:
            lines.setdefault(n // 3, []).append(zp.format_budget(max(1, k_max // 2)))
            lines.setdefault(2 * n // 3, []).append(zp.format_budget(k_max))
        return lines

    def on_line(self, line):
        if line.startswith("pose "):
            try:
                self.poses.append(zp.parse_pose(line))
            except zp.ProtocolError as e:
                self.fail(str(e))
        elif line.startswith("ack "):
            self.acks.append(zp.parse_ack(line))
        elif line.startswith("hello "):
            self.hello = zp.parse_hello(line)
        elif line.strip():
            self.fail("unexpected output line: %r" % line[:80])

    def run_pipe(self, out_dir):
        proc = subprocess.Popen(self.command(["--stdin"], out_dir), stdin=subprocess.PIPE,
                                stdout=subprocess.PIPE, text=True, bufsize=1)
        self.on_line(proc.stdout.readline())
        if self.hello is None:
            proc.kill()
            raise SystemExit("robot: zonemapd did not say hello")
        controls = self.plan()

        def send():
            try:
                for i, (stamp, pos, quat, feats) in enumerate(self.frames()):
                    for c in controls.get(i, []):
                        proc.stdin.write(c + "\n")
                    self.sent_odom[round(stamp, 6)] = (pos, quat)
                    proc.stdin.write(zp.format_frame(stamp, pos, quat, feats) + "\n")
                proc.stdin.close()
            except BrokenPipeError:
                pass

        writer = threading.Thread(target=send)
        writer.start()
        for line in proc.stdout:
            self.on_line(line)
        writer.join()
        return proc.wait()

    def run_udp(self, out_dir):
        proc = subprocess.Popen(self.command(["--udp", "0"], out_dir), stdin=subprocess.DEVNULL,
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        self.on_line(proc.stdout.readline())  # the hello line is written to stdout
        port = None
        for line in proc.stderr:
            if "listening on 127.0.0.1:" in line:
                port = int(line.rsplit(":", 1)[1])
                break
        if self.hello is None or port is None:
            proc.kill()
            raise SystemExit("robot: zonemapd did not say hello / listen")
        # Drain the rest of stdout/stderr so zonemapd never blocks on them.
        threading.Thread(target=proc.stdout.read, daemon=True).start()
        threading.Thread(target=proc.stderr.read, daemon=True).start()
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        sock.settimeout(self.args.timeout)
        to = ("127.0.0.1", port)
        controls = self.plan()

        def ask(line):
            sock.sendto(line.encode(), to)
            data, _ = sock.recvfrom(UDP_PAYLOAD_MAX)
            self.on_line(data.decode())

        truncated = 0
        for i, (stamp, pos, quat, feats) in enumerate(self.frames()):
            for c in controls.get(i, []):
                if len(c) > UDP_PAYLOAD_MAX:  # a plan too long for one datagram: thin it
                    c = zp.format_route(zp.route_from_truth(zp.read_tum(
                        os.path.join(self.args.scenario, "localization_gt.tum")), 4.0, 1000))
                ask(c)
            line = zp.format_frame(stamp, pos, quat, feats)
            while len(line) > UDP_PAYLOAD_MAX:  # one frame, one datagram: fewer features
                feats = feats[: len(feats) * 3 // 4]
                line = zp.format_frame(stamp, pos, quat, feats)
                truncated += 1
            self.sent_odom[round(stamp, 6)] = (pos, quat)
            ask(line)
        sock.sendto(b"", to)  # an empty datagram ends zonemapd's input
        if truncated:
            print("robot: %d frames had features dropped to fit a datagram" % truncated)
        return proc.wait()

    def check(self, frames_sent):
        if len(self.poses) != frames_sent:
            self.fail("%d pose lines for %d frames" % (len(self.poses), frames_sent))
        k_max = int(self.hello["k_max"])
        last = -math.inf
        for p in self.poses:
            if p["resident_keyframes"] > p["k_max"] and self.hello["policy"] not in ("basic",):
                self.fail("resident %d > K_max %d at %.3f" % (p["resident_keyframes"], p["k_max"],
                                                                 p["stamp"]))
            if p["stamp"] <= last:
                self.fail("stamps do not increase at %.3f" % p["stamp"])
            last = p["stamp"]
            odom = self.sent_odom.get(round(p["stamp"], 6))
            if odom is None:
                self.fail("a pose for a stamp never sent: %.6f" % p["stamp"])
                continue
            pos, quat = compose(p["map_from_odom_position"], p["map_from_odom_orientation_xyzw"],
                                odom[0], odom[1])
            if math.dist(pos, p["position"]) > 1e-3:
                self.fail("pose != map<-odom * odometry at %.3f (%.4f m)" %
                          (p["stamp"], math.dist(pos, p["position"])))
            cov = p["covariance"]
            if any(cov[6 * i + i] < 0 for i in range(6)) or any(math.isnan(c) for c in cov):
                self.fail("a covariance with a negative or NaN variance at %.3f" % p["stamp"])
        budgets = [a for a in self.acks if a["what"] == "budget"]
        if len(budgets) == 2:
            down, up = budgets
            if down["outcome"] != "ok" or down["resident"] > down["k_max"] and \
                    self.hello["policy"] != "basic":
                self.fail("budget down: %r" % down)
            if up["k_max"] != k_max:
                self.fail("budget back up: %r" % up)
        routes = [a for a in self.acks if a["what"] == "route"]
        if routes and routes[0]["outcome"] != "ok":
            self.fail("route refused: %r" % routes[0])

    def report(self):
        n = len(self.poses)
        by_status = {s: sum(1 for p in self.poses if p["status"] == s) for s in zp.STATUSES}
        print("robot: %d pose lines (protocol %d, policy %s, K_max %s): %s" % (
            n, self.hello["version"], self.hello["policy"], self.hello["k_max"],
            ", ".join("%s %d" % kv for kv in by_status.items())))
        for a in self.acks:
            print("robot: ack %s" % " ".join("%s=%s" % kv for kv in a.items()
                                               if kv[0] != "zones" or len(kv[1]) < 12))
        gt_path = os.path.join(self.args.scenario, "localization_gt.tum")
        if not os.path.exists(gt_path) or not self.poses:
            return
        gt = zp.read_tum(gt_path)
        # Covariance calibration against the ground truth: the squared Mahalanobis distance of
        # the horizontal error (95 % of a calibrated 2-D Gaussian falls within 5.991, chi-square
        # with 2 dof) and the heading error against its 1-sigma (95 % within 1.96 sigma).
        for status in ("localized", "dead_reckoning", "lost"):
            inside, yaw_inside, total, err2 = 0, 0, 0, 0.0
            for p in self.poses:
                truth = gt.get(round(p["stamp"], 6))
                if p["status"] != status or truth is None:
                    continue
                ex, ey = p["position"][0] - truth[0], p["position"][1] - truth[1]
                c = p["covariance"]
                a, b, d = c[0], c[1], c[7]
                det = a * d - b * b
                if det <= 0:
                    continue
                m2 = (d * ex * ex - 2 * b * ex * ey + a * ey * ey) / det
                inside += m2 <= 5.991
                dyaw = zp.yaw_of(p["orientation_xyzw"]) - zp.yaw_of(truth[3:7])
                dyaw = math.atan2(math.sin(dyaw), math.cos(dyaw))
                yaw_inside += abs(dyaw) <= 1.96 * math.sqrt(max(c[35], 1e-30))
                total += 1
                err2 += ex * ex + ey * ey
            if total:
                print("robot: %s: %d frames, horizontal error RMS %.3f m; within the 95 %% "
                      "ellipse of their covariance: %.1f %% (position), %.1f %% (heading)" % (
                          status, total, math.sqrt(err2 / total), 100.0 * inside / total,
                          100.0 * yaw_inside / total))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--zonemapd", required=True, help="the zonemapd binary")
    ap.add_argument("--scenario", required=True, help="a scenario directory (zonemap sim)")
    ap.add_argument("--profile", default="host")
    ap.add_argument("--policy")
    ap.add_argument("--memory-thr", help="zonemapd --memory-thr")
    ap.add_argument("--transport", choices=("pipe", "udp"), default="pipe")
    ap.add_argument("--frames", type=int, default=0, help="send only the first N frames")
    ap.add_argument("--max-features", type=int, default=2048)
    ap.add_argument("--blind", default="", help="frames sent without features: START:COUNT,...")
    ap.add_argument("--emulator", default="", help="command prefix, e.g. qemu-aarch64 -L SYSROOT")
    ap.add_argument("--timeout", type=float, default=120.0, help="seconds to wait for a reply (udp)")
    ap.add_argument("--out", help="zonemapd's run directory (default: a temporary one)")
    ap.add_argument("--check", action="store_true", help="exit 1 if a check fails")
    args = ap.parse_args()

    robot = Robot(args)
    with tempfile.TemporaryDirectory() as tmp:
        out_dir = args.out or os.path.join(tmp, "run")
        rc = robot.run_udp(out_dir) if args.transport == "udp" else robot.run_pipe(out_dir)
        if rc != 0:
            robot.fail("zonemapd exited with %d" % rc)
        frames_sent = len(robot.sent_odom)
        robot.check(frames_sent)
        robot.report()
    if robot.failures:
        print("robot: %d checks failed" % len(robot.failures), file=sys.stderr)
        return 1 if args.check else 0
    print("robot: every check passed (%s)" % args.transport)
    return 0


if __name__ == "__main__":
    sys.exit(main())
