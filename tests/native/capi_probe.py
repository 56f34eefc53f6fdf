"""librocks's C API through ctypes, in a process of its own without Taichi's Python package (its LLVM and the C
API's would share one process otherwise). Prints one JSON line.

    python capi_probe.py LIBROCKS open MODULE    -> {"opened": bool, "error": str}
    python capi_probe.py LIBROCKS calls MODULE   -> every bad call's status and message, whether the simulation
                                                    stepped on to the state of one that never saw them
"""

import ctypes as C
import json
import math
import sys


class Changes(C.Structure):
    _fields_ = [("count", C.c_int64), ("ids", C.POINTER(C.c_int32)), ("positions", C.POINTER(C.c_double)),
                ("phase", C.POINTER(C.c_int8)), ("orientations", C.POINTER(C.c_double))]


class Counts(C.Structure):
    _fields_ = [("time", C.c_double), ("steps", C.c_int64), ("rocks", C.c_int64), ("active", C.c_int64),
                ("launches", C.c_int64), ("recycles", C.c_int64), ("impacts", C.c_int64),
                ("impacts_dropped", C.c_int64)]


class Vehicle(C.Structure):
    _fields_ = [("name", C.c_char_p), ("live", C.c_int32), ("x", C.c_double), ("y", C.c_double),
                ("heading", C.c_double), ("speed", C.c_double)]


class Buffer(C.Structure):
    _fields_ = [("runtime", C.c_void_p), ("memory", C.c_uint64), ("offset", C.c_uint64), ("count", C.c_uint64),
                ("components", C.c_int32), ("type", C.c_int32), ("origin", C.c_double * 3)]


def load(path):
    lib = C.CDLL(path)
    lib.rocks_open.restype = C.c_void_p
    lib.rocks_open.argtypes = [C.c_char_p, C.c_char_p, C.c_size_t]
    lib.rocks_last_error.restype = C.c_char_p
    lib.rocks_last_error.argtypes = [C.c_void_p]
    lib.rocks_drive.argtypes = [C.c_void_p, C.c_char_p] + [C.c_double] * 6
    lib.rocks_advance_to.argtypes = [C.c_void_p, C.c_double]
    lib.rocks_changes.argtypes = [C.c_void_p, C.c_void_p]
    lib.rocks_counts.argtypes = [C.c_void_p, C.c_void_p]
    lib.rocks_vehicle.argtypes = [C.c_void_p, C.c_int, C.c_void_p]
    lib.rocks_buffer.argtypes = [C.c_void_p, C.c_char_p, C.c_void_p]
    lib.rocks_close.argtypes = [C.c_void_p]
    return lib


def open_sim(lib, folder):
    err = C.create_string_buffer(1024)
    sim = lib.rocks_open(folder.encode(), err, len(err))
    return sim, err.value.decode()


def state(lib, sim, mirror):
    ch = Changes()
    assert lib.rocks_changes(sim, C.byref(ch)) == 0, lib.rocks_last_error(sim)
    for k in range(ch.count):
        mirror[ch.ids[k]] = (ch.positions[3 * k], ch.positions[3 * k + 1], ch.positions[3 * k + 2], ch.phase[k])
    c = Counts()
    assert lib.rocks_counts(sim, C.byref(c)) == 0, lib.rocks_last_error(sim)
    return c.launches, c.recycles, c.steps


def calls(lib, folder):
    """Every bad call on one simulation between its frames; then both step 10 frames more."""
    a, _ = open_sim(lib, folder)
    b, _ = open_sim(lib, folder)
    ma, mb = {}, {}
    nan, inf = math.nan, math.inf
    errors = {}

    def note(name, status, sim=a):
        errors[name] = [status, lib.rocks_last_error(sim).decode() if sim else ""]

    for f in range(1, 11):
        for sim, m in ((a, ma), (b, mb)):
            assert lib.rocks_advance_to(sim, f / 60) == 0
            state(lib, sim, m)
    note("drive unknown", lib.rocks_drive(a, b"nobody", 0, 0, 0, nan, nan, nan))
    note("drive recorded", lib.rocks_drive(a, b"player", 0, 0, 0, nan, nan, nan))
    note("drive nan heading", lib.rocks_drive(a, b"chaser", 0, 0, nan, nan, nan, nan))
    note("drive inf x", lib.rocks_drive(a, b"chaser", inf, 0, 0, nan, nan, nan))
    note("drive inf speed", lib.rocks_drive(a, b"chaser", 0, 0, 0, inf, nan, nan))
    note("drive null", lib.rocks_drive(a, None, 0, 0, 0, nan, nan, nan))
    note("advance nan", lib.rocks_advance_to(a, nan))
    note("advance far", lib.rocks_advance_to(a, 1e12))
    note("changes null", lib.rocks_changes(a, None))
    note("vehicle index", lib.rocks_vehicle(a, 3, C.byref(Vehicle())))
    buf = Buffer()
    note("buffer name", lib.rocks_buffer(a, b"nothing", C.byref(buf)))
    note("null sim", lib.rocks_advance_to(None, 1.0), None)
    assert lib.rocks_buffer(a, b"drawn_pos", C.byref(buf)) == 0
    same = True
    for f in range(11, 21):
        counts = []
        for sim, m in ((a, ma), (b, mb)):
            assert lib.rocks_advance_to(sim, f / 60) == 0
            counts.append(state(lib, sim, m))
        same = same and ma == mb and counts[0] == counts[1]
    out = {"errors": errors, "same_after": same, "steps": counts[0][2] // 2,
           "buffer": {"count": buf.count, "components": buf.components}}
    lib.rocks_close(a)
    lib.rocks_close(b)
    return out


def main():
    lib = load(sys.argv[1])
    what, folder = sys.argv[2], sys.argv[3]
    if what == "open":
        sim, err = open_sim(lib, folder)
        print(json.dumps({"opened": bool(sim), "error": err}))
        if sim:
            lib.rocks_close(sim)
    else:
        print(json.dumps(calls(lib, folder)))


if __name__ == "__main__":
    main()
