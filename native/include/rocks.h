/* rocks.h: the rock system as a C library, for a game engine written in C or C++ (Unreal, Unity, Godot, in-house).
 *
 * A module folder written by `taichi-rocks aot SCENE --arch x64|vulkan --out DIR` holds a scene's step compiled
 * ahead of time, the bed's initial state and the vehicles' drives. This library opens it with Taichi's C API
 * (libtaichi_c_api) and steps it with no Python: the host side of a step (the vehicles' poses, the rear tires and
 * their rays, the bed following its vehicle, the floating origin, the hash table's fit, the impact events) is
 * computed here with the numbers the Python engine computes, so a module run here gives the Python twin's results
 * (on x64 to the bit). The manual, every function's contract and what is exported: docs/native.md.
 *
 * Threads: a RocksSim is used by one thread at a time. Errors: every function returns ROCKS_OK (0) or a negative
 * status; the message of the last failed call is rocks_last_error(sim). A failed call leaves the simulation as it
 * was, except after ROCKS_ERROR_DEVICE (the device failed in the middle of a step): then every later call that
 * steps or reads returns ROCKS_ERROR_STATE, and rocks_close is all that is left to do. No function aborts.
 */
#ifndef ROCKS_H
#define ROCKS_H

#include <stddef.h>
#include <stdint.h>

#if defined(_WIN32)
#define ROCKS_API __declspec(dllexport)
#else
#define ROCKS_API __attribute__((visibility("default")))
#endif

#ifdef __cplusplus
extern "C" {
#endif

#define ROCKS_VERSION 1 /* of this header; a module's manifest names the format it was written for */

enum RocksStatus {
  ROCKS_OK = 0,
  ROCKS_ERROR_ARGUMENT = -1, /* a bad argument (NULL, NaN, an unknown or scripted vehicle, ...): nothing changed */
  ROCKS_ERROR_MODULE = -2,   /* the module folder cannot be used: missing or broken files, another format,
                                Taichi version or backend than this library's */
  ROCKS_ERROR_DEVICE = -3,   /* Taichi's runtime failed (its message is in rocks_last_error) */
  ROCKS_ERROR_STATE = -4,    /* the simulation cannot go on after an earlier ROCKS_ERROR_DEVICE */
  ROCKS_ERROR_MEMORY = -5    /* out of host memory */
};

typedef struct RocksSim RocksSim;

/* The rocks whose drawn state changed since the previous rocks_changes (every rock the first time): row k is
 * rock ids[k] at positions[3k .. 3k+2] (world coordinates, m, float64), with phase[k] (0 resting, 1 flying,
 * 2 sliding) and, when the module tracks tumbling, orientations[4k .. 4k+3] (quaternion x, y, z, w; NULL
 * otherwise). The arrays belong to the library and stay valid until the next rocks_changes or rocks_close. */
typedef struct RocksChanges {
  int64_t count;
  const int32_t* ids;
  const double* positions;
  const int8_t* phase;
  const double* orientations;
} RocksChanges;

/* One stone hitting a vehicle (the fields of Python's Simulation.impacts(), docs/physics.md): point, normal in the
 * frame of the vehicle hit (x forward, y left, z up); part and damage index the labels of docs/native.md. */
typedef struct RocksImpact {
  double time;            /* s, when the stone touched the body */
  int64_t step;           /* the step it touched in */
  int32_t vehicle;        /* the vehicle hit (index in the module's vehicles) */
  int32_t rock;           /* the stone's id */
  int32_t thrower;        /* the vehicle whose tire threw it (-1: unknown) */
  int8_t part;            /* what was hit */
  int8_t damage;          /* damage class: 0 mark, 1 chip, 2 crack */
  double point[3];        /* m, the contact point */
  double normal[3];       /* outward unit normal of the body there */
  double speed;           /* m/s, the stone's speed relative to the body */
  double normal_speed;    /* m/s, its component into the body */
  double normal_momentum; /* N s */
  double energy;          /* J, 1/2 m speed^2 */
  double radius;          /* m, the stone's radius */
} RocksImpact;

/* The events since the previous rocks_impacts, in (step, rock, vehicle) order; the array belongs to the library
 * and stays valid until the next rocks_impacts or rocks_close. */
typedef struct RocksImpacts {
  int64_t count;
  const RocksImpact* events;
} RocksImpacts;

typedef struct RocksCounts {
  double time;              /* s, the simulation's clock */
  int64_t steps;            /* steps taken since time 0 */
  int64_t rocks;            /* rocks in the bed (ids 0 .. rocks - 1) */
  int64_t active;           /* rocks in the active list (those a step visits) */
  int64_t launches;         /* rocks launched by a tire since time 0 */
  int64_t recycles;         /* rocks recycled to the bed's leading edge since time 0 */
  int64_t impacts;          /* impact events handed out by rocks_impacts so far */
  int64_t impacts_dropped;  /* events lost to a full buffer */
} RocksCounts;

typedef struct RocksVehicle {
  const char* name; /* valid until rocks_close */
  int32_t live;     /* 1: driven by rocks_drive; 0: replays its recorded drive */
  double x, y;      /* m, world: where its body centre is now */
  double heading;   /* rad, counter-clockwise from +x */
  double speed;     /* m/s along the heading */
} RocksVehicle;

/* A World buffer as Taichi holds it, for a renderer that reads it on the device (docs/native.md, "Sharing the
 * rocks with a renderer"): `runtime` is the TiRuntime and `memory` the TiMemory (taichi_core.h handles) of the
 * group holding field `name`, which starts `offset` bytes into it and holds `count` elements of `components`
 * values of `type` (TiDataType); positions in it are local: world = origin + local. */
typedef struct RocksBuffer {
  void* runtime;
  uint64_t memory;
  uint64_t offset;
  uint64_t count;
  int32_t components;
  int32_t type;
  double origin[3];
} RocksBuffer;

/* Opens the module folder `module_dir` and builds its simulation at time 0 (the Taichi runtime of the module's
 * backend, its kernels, the World's buffers). Returns NULL on failure, with a one-line message in `error` (up to
 * error_size bytes, NUL-terminated; `error` may be NULL). On x64 the Taichi runtime's bitcode is taken from the
 * environment's TI_LIB_DIR if set, else from the Taichi installation this library was built against. */
ROCKS_API RocksSim* rocks_open(const char* module_dir, char* error, size_t error_size);

/* The message of the last call on `sim` that failed ("" if none). Valid until the next call on `sim`. */
ROCKS_API const char* rocks_last_error(const RocksSim* sim);

/* Where live vehicle `vehicle` will be at the end of the next rocks_advance_to: world x, y (m), heading (rad);
 * speed (m/s along the heading), yaw_rate (rad/s) and wheel_spin (rad/s of the rear wheels) may be NaN: not given
 * (the speed and yaw rate are then derived from the motion, the wheels roll). A later call before the advance
 * replaces this one. ROCKS_ERROR_ARGUMENT: an unknown vehicle, one replaying a recorded drive, a position or
 * heading that is not finite, an infinite speed, yaw rate or spin. Python's Simulation.drive (docs/drives.md). */
ROCKS_API int rocks_drive(RocksSim* sim, const char* vehicle, double x, double y, double heading, double speed,
                          double yaw_rate, double wheel_spin);

/* Steps to exactly time t (s): whole steps of the module's dt, then a shorter one if dt does not divide the
 * interval; a time at or before the clock takes no step. ROCKS_ERROR_ARGUMENT: t is NaN or infinite, or past the
 * last step the kernels count (2^31 - 1 steps). */
ROCKS_API int rocks_advance_to(RocksSim* sim, double t);

/* The rocks whose drawn state changed since the previous call (RocksChanges). */
ROCKS_API int rocks_changes(RocksSim* sim, RocksChanges* out);

/* The impact events since the previous call (RocksImpacts); none in a module without impacts. */
ROCKS_API int rocks_impacts(RocksSim* sim, RocksImpacts* out);

/* The clock and the counts (RocksCounts); `active`, `launches` and `recycles` are read from the device. */
ROCKS_API int rocks_counts(RocksSim* sim, RocksCounts* out);

/* How many vehicles the module has (0 for a NULL sim). */
ROCKS_API int rocks_vehicle_count(const RocksSim* sim);

/* Vehicle `index`'s name, kind and pose now. ROCKS_ERROR_ARGUMENT: index out of range. */
ROCKS_API int rocks_vehicle(RocksSim* sim, int index, RocksVehicle* out);

/* Field `name` of the World on the device (RocksBuffer); the names: the module's manifest.json ("fields").
 * ROCKS_ERROR_ARGUMENT: no such field. */
ROCKS_API int rocks_buffer(RocksSim* sim, const char* name, RocksBuffer* out);

/* Frees everything of `sim` (NULL: nothing). */
ROCKS_API void rocks_close(RocksSim* sim);

#ifdef __cplusplus
}
#endif

#endif /* ROCKS_H */
