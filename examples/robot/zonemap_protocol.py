"""The zonemapd line protocol, robot side (Python 3, standard library only).

In (robot -> zonemapd), one line each (README, "Driving zonemapd from a robot"):
    frame <stamp> <tx> <ty> <tz> <qx> <qy> <qz> <qw> <n> [<u> <v> <hex64>] x n
    route <n> [<x> <y> <z>] x n
    budget <keyframes>
Out (zonemapd -> robot):
    hello zonemapd <version> key value ...
    pose <stamp> <tx> <ty> <tz> <qx> <qy> <qz> <qw> <version> <map<-odom x7> <status>
         <frames_since_fix> <zone> <closure> <inliers> <resident> <k_max> <tick_ms>
         <malformed> <covariance x36>
    ack route <ok|rejected> <waypoints> <zones> [<zone>] x zones
    ack budget <ok|clamped|ignored|refused> <requested> <k_max> <resident> <unloaded>

Also a reader for a simulated scenario's frames.bin (lib/runtime/frames_file.h), so the example
robot can replay a recorded run as if its camera and odometry produced it.
"""

import math
import struct

POSE_PROTOCOL_VERSION = 1
POSE_TOKENS = 62
STATUSES = ("localized", "dead_reckoning", "lost")


def format_frame(stamp, position, quaternion_xyzw, features=()):
    """One frame line. features: iterable of (u, v, descriptor bytes of length 32)."""
    features = list(features)
    head = "frame %.6f %.6f %.6f %.6f %.9f %.9f %.9f %.9f %d" % (
        (stamp,) + tuple(position) + tuple(quaternion_xyzw) + (len(features),))
    parts = [head]
    for u, v, d in features:
        parts.append("%.3f %.3f %s" % (u, v, d.hex()))
    return " ".join(parts)


def format_route(waypoints):
    """One route line from (x, y, z) map-frame waypoints; [] clears the route."""
    return " ".join(["route %d" % len(waypoints)] +
                    ["%.3f %.3f %.3f" % tuple(p) for p in waypoints])


def format_budget(keyframes):
    return "budget %d" % keyframes


class ProtocolError(ValueError):
    pass


def parse_hello(line):
    t = line.split()
    if len(t) < 3 or t[0] != "hello" or t[1] != "zonemapd":
        raise ProtocolError("not a hello line: %r" % line[:80])
    info = {"version": int(t[2])}
    rest = t[3:]
    for key, value in zip(rest[0::2], rest[1::2]):
        info[key] = value
    return info


def parse_pose(line):
    """A pose line as a dict; ProtocolError on anything else, including another version."""
    t = line.split()
    if not t or t[0] != "pose":
        raise ProtocolError("not a pose line: %r" % line[:80])
    if len(t) != POSE_TOKENS:
        raise ProtocolError("a pose line has %d tokens, not %d" % (len(t), POSE_TOKENS))
    version = int(t[9])
    if version != POSE_PROTOCOL_VERSION:
        raise ProtocolError("pose protocol version %d, this robot speaks %d" %
                            (version, POSE_PROTOCOL_VERSION))
    f = [float(x) for x in t[1:9]]
    mo = [float(x) for x in t[10:17]]
    status = t[17]
    if status not in STATUSES:
        raise ProtocolError("unknown status %r" % status)
    return {
        "stamp": f[0],
        "position": tuple(f[1:4]),
        "orientation_xyzw": tuple(f[4:8]),
        "version": version,
        "map_from_odom_position": tuple(mo[0:3]),
        "map_from_odom_orientation_xyzw": tuple(mo[3:7]),
        "status": status,
        "frames_since_fix": int(t[18]),
        "zone": int(t[19]),
        "loop_closure": t[20] == "1",
        "inliers": int(t[21]),
        "resident_keyframes": int(t[22]),
        "k_max": int(t[23]),
        "tick_ms": float(t[24]),
        "malformed": int(t[25]),
        # Row-major 6x6, x y z then rotation about X Y Z: geometry_msgs/PoseWithCovariance.
        "covariance": [float(x) for x in t[26:62]],
    }


def parse_ack(line):
    t = line.split()
    if len(t) < 3 or t[0] != "ack":
        raise ProtocolError("not an ack line: %r" % line[:80])
    if t[1] == "route":
        n_zones = int(t[4])
        return {"what": "route", "outcome": t[2], "waypoints": int(t[3]),
                "zones": [int(z) for z in t[5:5 + n_zones]]}
    if t[1] == "budget":
        return {"what": "budget", "outcome": t[2], "requested": int(t[3]), "k_max": int(t[4]),
                "resident": int(t[5]), "unloaded": int(t[6])}
    raise ProtocolError("unknown ack %r" % t[1])


class FramesFile:
    """Reads frames.bin (zonemap sim's localization run) frame by frame."""
    HEADER = 128
    RECORD = 80

    def __init__(self, path):
        self._f = open(path, "rb")
        h = self._f.read(self.HEADER)
        if len(h) != self.HEADER or struct.unpack_from("<I", h, 0)[0] != 0x52464D5A:
            raise ProtocolError("%s is not a frames file" % path)
        self.count = struct.unpack_from("<Q", h, 8)[0]
        self.max_features = struct.unpack_from("<I", h, 16)[0]
        self.rate_hz = struct.unpack_from("<d", h, 64)[0]

    def __iter__(self):
        self._f.seek(self.HEADER)
        for _ in range(self.count):
            rec = self._f.read(self.RECORD)
            if len(rec) != self.RECORD:
                raise ProtocolError("frames file truncated")
            stamp = struct.unpack_from("<d", rec, 8)[0]
            pose = struct.unpack_from("<7d", rec, 16)
            n = struct.unpack_from("<I", rec, 72)[0]
            desc = self._f.read(32 * n)
            kps = struct.unpack("<%df" % (2 * n), self._f.read(8 * n))
            features = [(kps[2 * i], kps[2 * i + 1], desc[32 * i:32 * i + 32]) for i in range(n)]
            yield stamp, pose[0:3], pose[3:7], features

    def close(self):
        self._f.close()


def read_tum(path):
    """stamp -> (x, y, z, qx, qy, qz, qw) of a TUM trajectory file."""
    out = {}
    with open(path) as f:
        for line in f:
            if not line.strip() or line.startswith("#"):
                continue
            v = line.split()
            out[round(float(v[0]), 6)] = tuple(float(x) for x in v[1:8])
    return out


def yaw_of(q_xyzw):
    x, y, z, w = q_xyzw
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def route_from_truth(gt, spacing_m=1.0, limit=4096):
    """A path (stamp -> (x, y, z), e.g. read_tum) as a navigation stack's plan: a waypoint every
    spacing_m metres, at most `limit` (zonemapd's max_route_waypoints; thinned evenly)."""
    pts = [gt[k][:3] for k in sorted(gt)]
    out = []
    for p in pts:
        if not out or math.dist(p, out[-1]) >= spacing_m:
            out.append(p)
    if len(out) > limit:  # keep the plan within zonemapd's reserve: thin it evenly
        step = len(out) / float(limit)
        out = [out[int(i * step)] for i in range(limit)]
    return out
