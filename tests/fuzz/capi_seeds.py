#!/usr/bin/env python3
"""Writes the seed corpus of fuzz_capi (tests/fuzz/corpus/capi/).

Each seed is the byte encoding capi_fuzz.cpp decodes: the engine definition
(shape, source, settings bytes and the table indices they ask for), then the
calls. Run from the repository root after changing the decoding:
    python3 tests/fuzz/capi_seeds.py
"""
import os

# Calls (first byte of each, modulo 10) and their argument bytes.
STEP, STEP2, DROP_VERTEX, DROP_POINT, COPY, STATS, THREADS, SAVE, LOAD, GETTERS = range(10)


def step(i):  # kFrameDt index
    return [STEP, i]


def drop_vertex(choice, fields=0, *values):  # choice: vertex table index; fields: drop() bit mask
    return [DROP_VERTEX, fields, *values, choice, 1]  # 1: not a NULL drop


def copy(what, capacity=0, null=1):
    return [COPY, what, capacity, null]


def definition(shape=0, source=0, settings=0, *extra):
    return [shape, source, settings, *extra]


common = step(1) * 3 + drop_vertex(1) + step(1) + copy(0) + copy(6) + [STATS, 1] + [SAVE, 1] + step(1) + \
    [LOAD, 0] + step(1) + [LOAD, 3, 128] + [GETTERS]

seeds = {
    # 2 x 2 static patch: steps, a drop, copies, statistics, save, load, a truncated load.
    "static_roundtrip": definition(0, 0, 0) + common,
    # 4 x 4 two-way Bullet cloth pinned at its top corners.
    "bullet_two_way": definition(2, 2 | 0x80 | 0x20, 0) + common,
    # A rigid patch spinning about z at 1 rad/s (settings 0x20: axis 2, kAnyDouble[1]).
    "rigid_spin": definition(1, 1, 0x20, 2, 1) + common,
    # Frame times 1, 1 + 1e-7, -0.01, 1e308, NaN, inf, -inf, 1e-300.
    "hostile_frame_times": definition(0, 0, 0) + sum((step(i) for i in range(6, 14)), []) + [GETTERS],
    # Drops: radius 0 and NaN, negative and infinite masses, vertex out of range, a NULL drop,
    # a point at 1e308 and at NaN.
    "hostile_drops": definition(0, 0, 0) + drop_vertex(0, 1, 3) + drop_vertex(0, 1, 9) + drop_vertex(0, 2, 3) +
    drop_vertex(0, 4, 10) + drop_vertex(3, 0) + drop_vertex(5, 0) + [DROP_VERTEX, 0, 1, 0] +  # NULL drop
   
    [DROP_POINT, 10, 0, 0, 0, 1] + [DROP_POINT, 12, 1, 1, 0, 1] + [DROP_POINT, 7, 0, 0, 0, 1] + step(1),
    # Definitions refused: time step 0, NaN; steps per call 0; gravity 1e308; diffusivity NaN.
    "bad_time_step": definition(0, 0, 0x01, 4),
    "nan_time_step": definition(0, 0, 0x01, 6),
    "zero_steps_per_call": definition(0, 0, 0x02, 3),
    "huge_gravity": definition(0, 0, 0x10, 0, 11) + step(1),
    "nan_diffusivity": definition(0, 0, 0x04, 13),
    "not_a_source": definition(0, 6, 0),  # source 3
    "source_minus_one": definition(0, 7, 0),
    "pin_out_of_range": definition(0, 2 | 0x40, 0, 200),
    "face_out_of_range": definition(0x10, 0, 0, 255),
    "vertex_at_1e308": definition(0x08, 0, 0, 10) + step(1),
    # A weave preset on every face, then an unknown one.
    "weave_preset": definition(0, 0, 0x40, 2, 1) + step(1) * 2 + copy(6),
    "unknown_preset": definition(0, 0, 0x40, 4, 1),
    # Every copy with every capacity (need, need + 5, need - 1, 0, -1, INT_MIN) and NULL.
    "copies": definition(1, 0, 0) + step(1) + sum((copy(w, c, 1) for w in range(8) for c in (0, 2, 3, 4, 5, 6)), []) +
    copy(0, 0, 0) + copy(5, 0, 0) + copy(6, 0, 0) + [COPY, 6, 6, 0, 1],
    # Thread counts 1, 0, 2, -1, 1025, INT_MAX, INT_MIN; statistics into NULL.
    "threads": definition(0, 0, 0) + sum(([THREADS, i] for i in range(7)), []) + [STATS, 0] + step(1),
    # Loads: a missing path, /dev/zero, before and after a save.
    "loads": definition(0, 0, 0) + [LOAD, 1] + [LOAD, 2] + [LOAD, 0] + [SAVE, 0] + [SAVE, 1] + [LOAD, 2] +
    [LOAD, 3, 0] + [LOAD, 3, 255] + [LOAD, 0] + step(1),
}

folder = os.path.join(os.path.dirname(os.path.abspath(__file__)), "corpus", "capi")
os.makedirs(folder, exist_ok=True)
for name, data in seeds.items():
    with open(os.path.join(folder, name + ".bin"), "wb") as f:
        f.write(bytes(b & 0xFF for b in data))
print(f"{len(seeds)} seeds in {folder}")
