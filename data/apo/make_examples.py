#!/usr/bin/env python3
"""Writes the example observation files of data/apo/ (Suehiro & Ikeuchi §5.1–5.3): exact geometry, the human's
unobserved 1 mm adjustment, and seeded noise (±0.2 mm, ±0.086°) on every observed pose. Run from the repository
top: data/apo/make_examples.py. The same scenes are built in C++ by tests/face_contact/apo_examples.h."""
import json
import math
import random


def rot(a, b, c):
    """Rx(a) Ry(b) Rz(c), radians."""
    ca, sa, cb, sb, cc, sc = math.cos(a), math.sin(a), math.cos(b), math.sin(b), math.cos(c), math.sin(c)
    rx = [[1, 0, 0], [0, ca, -sa], [0, sa, ca]]
    ry = [[cb, 0, sb], [0, 1, 0], [-sb, 0, cb]]
    rz = [[cc, -sc, 0], [sc, cc, 0], [0, 0, 1]]
    return mul(mul(rx, ry), rz)


def mul(a, b):
    return [[sum(a[i][k] * b[k][j] for k in range(3)) for j in range(3)] for i in range(3)]


def pose(t, rdeg=(0, 0, 0)):
    return (list(t), rot(*[math.radians(x) for x in rdeg]))


def noisy(p, rng, shift=(0, 0, 0), nt=2e-4, nr=1.5e-3):
    t, r = p
    dq = [rng.uniform(-nt, nt) for _ in range(3)]
    da = [rng.uniform(-nr, nr) for _ in range(3)]
    dr = rot(*da)
    t2 = [t[i] + sum(r[i][k] * dq[k] for k in range(3)) + shift[i] for i in range(3)]
    return (t2, mul(r, dr))


def to_json(p):
    t, r = p
    b = math.asin(max(-1, min(1, r[0][2])))
    a = math.atan2(-r[1][2], r[2][2])
    c = math.atan2(-r[0][1], r[0][0])
    return {"t": [round(x, 7) for x in t], "rxyz_deg": [round(math.degrees(x), 6) for x in (a, b, c)]}


def castle(w, h, n, d, l):
    return {"prism": {"profile": [[-w / 2, 0], [w / 2, 0], [w / 2, h], [n / 2, h], [n / 2, h - d], [-n / 2, h - d],
                                  [-n / 2, h], [-w / 2, h]], "length": l}}


def channel(w, h, n, c, l):
    return {"prism": {"profile": [[-w / 2, 0], [-n / 2, 0], [-n / 2, c], [n / 2, c], [n / 2, 0], [w / 2, 0],
                                  [w / 2, h], [-w / 2, h]], "length": l}}


TABLE = {"id": "table", "stable": True, "model": {"box": [1, 1, 0.05]}, "pose": {"t": [0, 0, -0.05], "rxyz_deg": [0, 0, 0]}}


def write(name, description, objects, operations):
    doc = {"description": description, "settings": {"mode": "iterative", "contact_distance": 0.003,
                                                    "contact_angle_deg": 3, "residue_threshold": 1e-9,
                                                    "characteristic_length": 0.1},
           "objects": objects, "operations": operations}
    with open(f"data/apo/{name}.json", "w") as f:
        json.dump(doc, f, indent=1)
        f.write("\n")


rng = random.Random(51)
write("castles_stick", "Suehiro & Ikeuchi 5.1: castle1 on the table, castle2 upside down on castle1, a stick "
      "through the tunnel of their notches. Castle2 was observed 1 mm off in x (the human fixed it unobserved): "
      "T3 alone fails, {T3, T2} succeeds.",
      [TABLE, {"id": "castle1", "model": castle(0.08, 0.04, 0.02, 0.02, 0.06)},
       {"id": "castle2", "model": castle(0.08, 0.04, 0.02, 0.02, 0.06)},
       {"id": "stick", "model": {"box": [0.02, 0.2, 0.04]}}],
      [{"object": "castle1", "pose": to_json(noisy(pose((0, 0, 0)), rng))},
       {"object": "castle2", "pose": to_json(noisy(pose((0, 0, 0.08), (0, 180, 0)), rng, shift=(0.001, 0, 0)))},
       {"object": "stick", "pose": to_json(noisy(pose((0, 0, 0.02)), rng))}])

rng = random.Random(52)
pillar = castle(0.04, 0.05, 0.02, 0.01, 0.04)
write("sub_assembly", "Suehiro & Ikeuchi 5.2: castles on the table, a cube (U-channel) on castle1, a stick into "
      "the cube (sub-assembly), cube and stick onto both castles. Castle2 was observed 1 mm off in y: the trials "
      "are {T5}, {T5,T4}, {T5,T4,T3}, {T5,T4,T3,T2}.",
      [TABLE, {"id": "castle1", "model": pillar}, {"id": "castle2", "model": pillar},
       {"id": "cube", "model": channel(0.04, 0.04, 0.02, 0.02, 0.04)},
       {"id": "stick", "model": {"box": [0.02, 0.3, 0.02]}}],
      [{"object": "castle1", "pose": to_json(noisy(pose((-0.1, 0, 0), (0, 0, 90)), rng))},
       {"object": "castle2", "pose": to_json(noisy(pose((0.1, 0, 0), (0, 0, 90)), rng, shift=(0, 0.001, 0)))},
       {"object": "cube", "pose": to_json(noisy(pose((-0.1, 0, 0.05)), rng))},
       {"object": "stick", "pose": to_json(noisy(pose((-0.1, 0, 0.05)), rng))},
       {"object": "cube", "carries": ["stick"], "pose": to_json(noisy(pose((0, 0, 0.04), (0, 0, 90)), rng))}])

rng = random.Random(53)
write("disappeared_relation", "Suehiro & Ikeuchi 5.3: castle1 on the table, a cube as a fixture, castle2 pushed "
      "against the cube, the cube removed, a stick onto both castles. Cube and castle2 were observed 1 mm off in "
      "y: the trials are {T5}, {T5,T3}, {T5,T3,T2}; T2 is reached through the disappeared castle2-cube relation.",
      [TABLE, {"id": "castle1", "model": pillar}, {"id": "cube", "model": {"box": [0.04, 0.04, 0.04]}},
       {"id": "castle2", "model": pillar}, {"id": "stick", "model": {"box": [0.02, 0.3, 0.02]}}],
      [{"object": "castle1", "pose": to_json(noisy(pose((-0.1, 0, 0), (0, 0, 90)), rng))},
       {"object": "cube", "pose": to_json(noisy(pose((0.1, -0.04, 0)), rng, shift=(0, 0.001, 0)))},
       {"object": "castle2", "pose": to_json(noisy(pose((0.1, 0, 0), (0, 0, 90)), rng, shift=(0, 0.001, 0)))},
       {"object": "cube", "remove": True},
       {"object": "stick", "pose": to_json(noisy(pose((0, 0, 0.04), (0, 0, 90)), rng))}])
