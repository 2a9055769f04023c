#!/usr/bin/python3
"""A Foxglove WebSocket client of our own (the standard library only), as Foxglove connects to
`cellsim bridge`: the handshake, serverInfo and advertise, subscriptions and the messages of
three topics, each decoded far enough to be sure of it; then clients that break the protocol,
each refused with its reason while the first goes on receiving.

    foxglove_client.py PORT
"""
import base64
import hashlib
import json
import re
import os
import socket
import struct
import sys
import time

PORT = int(sys.argv[1])
GUID = "258EAFA5-E914-47DA-95CA-C5AB0DC85B11"


def fail(why):
    print("FAIL:", why)
    sys.exit(1)


def connect(protocol="foxglove.websocket.v1", key=None):
    s = socket.create_connection(("127.0.0.1", PORT), timeout=60)
    key = key or base64.b64encode(os.urandom(16)).decode()
    req = (f"GET / HTTP/1.1\r\nHost: 127.0.0.1:{PORT}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
           f"Sec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\nSec-WebSocket-Protocol: {protocol}\r\n\r\n")
    s.sendall(req.encode())
    head = b""
    while b"\r\n\r\n" not in head:
        chunk = s.recv(1)
        if not chunk:
            break
        head += chunk
    return s, key, head.decode(errors="replace")


def recv_exact(s, n):
    out = b""
    while len(out) < n:
        chunk = s.recv(n - len(out))
        if not chunk:
            fail(f"the server closed the connection ({len(out)} of {n} bytes)")
        out += chunk
    return out


def read_frame(s):
    b0, b1 = recv_exact(s, 2)
    if b1 & 0x80:
        fail("a masked frame from the server")
    n = b1 & 0x7F
    if n == 126:
        n = struct.unpack(">H", recv_exact(s, 2))[0]
    elif n == 127:
        n = struct.unpack(">Q", recv_exact(s, 8))[0]
    return b0 & 0x0F, recv_exact(s, n)


def send_frame(s, opcode, payload, masked=True):
    head = bytes([0x80 | opcode])
    mask = os.urandom(4) if masked else b""
    n = len(payload)
    bit = 0x80 if masked else 0
    head += bytes([bit | n]) if n < 126 else bytes([bit | 126]) + struct.pack(">H", n) if n < 65536 else \
        bytes([bit | 127]) + struct.pack(">Q", n)
    body = bytes(c ^ mask[i % 4] for i, c in enumerate(payload)) if masked else payload
    s.sendall(head + mask + body)


def send_json(s, obj):
    send_frame(s, 1, json.dumps(obj).encode())


def image_size(cdr):
    """height and width of a sensor_msgs/Image's CDR (little-endian, after its 4-byte header)."""
    if cdr[:2] != b"\x00\x01":
        fail(f"not little-endian CDR: {cdr[:4].hex()}")
    body = cdr[4:]
    at = 8  # stamp: sec, nanosec
    (n,) = struct.unpack_from("<I", body, at)
    at += 4 + n
    at = (at + 3) & ~3
    return struct.unpack_from("<II", body, at)


LAYOUT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "docs", "foxglove", "cell_layout.json")


def check_layout(channels):
    """The shipped Foxglove layout (docs/foxglove/cell_layout.json) against what the server
    advertises: every panel of its tree configured, every topic it names advertised, every field
    of a message path in that topic's schema."""
    layout = json.load(open(LAYOUT, encoding="utf-8"))
    panels = layout["configById"]

    def leaves(node):
        if isinstance(node, str):
            return [node]
        return leaves(node["first"]) + leaves(node["second"])
    shown = leaves(layout["layout"])
    if sorted(shown) != sorted(panels):
        fail(f"layout: panels in the tree {sorted(shown)}, configured {sorted(panels)}")
    paths, topics = [], []
    for name, config in panels.items():
        image = config.get("imageMode", {})
        topics += [image[k] for k in ("imageTopic", "calibrationTopic") if k in image] + list(image.get("annotations", {}))
        topics += [layer["topic"] for layer in config.get("layers", {}).values() if "topic" in layer]
        topics += list(config.get("topics", {}))
        paths += [p["value"] for p in config.get("paths", [])] + ([config["topicPath"]] if "topicPath" in config else [])
    for path in paths:
        topic, *fields = path.split(".")
        topics.append(topic)
        schema = channels.get(topic, {}).get("schema", "")
        for field in fields:
            if not re.search(rf"^\s*[\w/\[\]<=]+\s+{re.escape(field)}\b", schema, re.M):
                fail(f"layout: {path}: no field '{field}' in the schema of {topic}")
    missing = sorted(set(t for t in topics if t not in channels))
    if missing:
        fail(f"layout: topics not advertised: {missing}")
    print(f"layout: {len(panels)} panels, {len(set(topics))} topics and {len(paths)} message paths, all advertised")


def main():
    s, key, head = connect()
    if not head.startswith("HTTP/1.1 101"):
        fail(f"handshake: {head!r}")
    want = base64.b64encode(hashlib.sha1((key + GUID).encode()).digest()).decode()
    if f"Sec-WebSocket-Accept: {want}" not in head or "Sec-WebSocket-Protocol: foxglove.websocket.v1" not in head:
        fail(f"handshake headers: {head!r}")
    op, info = read_frame(s)
    info = json.loads(info)
    op, adv = read_frame(s)
    adv = json.loads(adv)
    if info.get("op") != "serverInfo" or adv.get("op") != "advertise":
        fail(f"first messages: {info}, {adv.get('op')}")
    channels = {c["topic"]: c for c in adv["channels"]}
    image = channels.get("/camera/image_raw")
    if not image or image["encoding"] != "cdr" or image["schemaEncoding"] != "ros2msg" or \
            image["schemaName"] != "sensor_msgs/msg/Image" or "uint32 height" not in image["schema"]:
        fail(f"the image channel: {image and {k: v for k, v in image.items() if k != 'schema'}}")
    drawn = channels.get("/servo/annotations")
    if not drawn or drawn["schemaName"] != "foxglove_msgs/msg/ImageAnnotations" or "CircleAnnotation[] circles" not in \
            drawn["schema"].replace("foxglove_msgs/", ""):
        fail(f"the annotations channel: {drawn and drawn['schemaName']}")
    for topic in ("/servo/status", "/tf", "/robot_description", "/joint_states", "/camera/camera_info"):
        if topic not in channels:
            fail(f"no channel {topic} in {sorted(channels)}")
    check_layout(channels)
    wanted = {7: "/camera/image_raw", 8: "/servo/status", 9: "/tf", 11: "/servo/annotations"}
    send_json(s, {"op": "subscribe", "subscriptions": [{"id": i, "channelId": channels[t]["id"]} for i, t in wanted.items()]})
    send_json(s, {"op": "subscribe", "subscriptions": [{"id": 10, "channelId": 999}]})
    send_json(s, {"op": "frobnicate"})
    statuses, counts = [], {i: 0 for i in wanted}
    deadline = time.time() + 90
    while min(counts.values()) < 3 and time.time() < deadline:
        op, payload = read_frame(s)
        if op == 1:
            statuses.append(json.loads(payload))
            continue
        if op != 2 or payload[0] != 1:
            fail(f"frame opcode {op}, message opcode {payload[:1].hex()}")
        sub, stamp = struct.unpack_from("<IQ", payload, 1)
        cdr = payload[13:]
        if sub not in counts:
            fail(f"a message for subscription {sub}, which was never made")
        counts[sub] += 1
        if sub == 7:
            h, w = image_size(cdr)
            if (h, w) != (480, 640) or len(cdr) < 640 * 480 * 3:
                fail(f"image {w} x {h}, {len(cdr)} bytes")
        if sub == 11:
            # ImageAnnotations: its circles first (a ring per decoded spot, and per desired point),
            # and each decoded spot's id as a text "row,col"
            (circles,) = struct.unpack_from("<I", cdr, 4)
            if circles == 0 or not re.search(rb"\d+,\d+\x00", cdr):
                fail(f"annotations with {circles} circles and no id label")
    if min(counts.values()) < 3:
        fail(f"messages received per subscription: {counts}")
    messages = " | ".join(st["message"] for st in statuses)
    if "no channel 999" not in messages or "'frobnicate' is not supported" not in messages:
        fail(f"statuses: {statuses}")
    print(f"bridge: {len(channels)} channels; image 640 x 480, servo status, tf, annotations received {counts}; "
          f"statuses: {messages}")

    # clients that break the protocol: each told why and closed
    bad, _, _ = connect()
    read_frame(bad), read_frame(bad)
    send_frame(bad, 1, b'{"op":"subscribe"}', masked=False)
    while True:
        op, payload = read_frame(bad)
        if op == 8:
            break
    code = struct.unpack(">H", payload[:2])[0]
    if code != 1002 or b"unmasked" not in payload:
        fail(f"an unmasked frame: close {code} {payload[2:]!r}")
    _, _, head = connect(protocol="something.else")
    if not head.startswith("HTTP/1.1 400"):
        fail(f"a client without the subprotocol: {head!r}")
    long = socket.create_connection(("127.0.0.1", PORT), timeout=60)
    long.sendall(b"GET / HTTP/1.1\r\n" + b"X-Long: " + b"a" * 9000)
    reply = long.recv(200).decode(errors="replace")
    if not reply.startswith("HTTP/1.1 400") or "8192" not in long.recv(400).decode(errors="replace") + reply:
        fail(f"an endless handshake: {reply!r}")
    big, _, _ = connect()
    read_frame(big), read_frame(big)
    send_frame(big, 1, b" " * 70000)
    while True:
        op, payload = read_frame(big)
        if op == 8:
            break
    if b"longer than 65536" not in payload:
        fail(f"a 70000-byte frame: close {payload!r}")
    print("bridge: unmasked frame, wrong subprotocol, endless handshake, oversized frame: each refused with its reason")

    # the first client still receives
    got = 0
    while got < 2:
        op, payload = read_frame(s)
        got += op == 2
    print("bridge: the first viewer receives on")


if __name__ == "__main__":
    main()
