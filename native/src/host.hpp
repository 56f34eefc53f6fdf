// The host side of a step, ported from the Python engine with its numbers: the vehicles' poses (motion/vehicles.py
// Fleet.poses), their rear tires (Fleet.rear_tires), the tire rays and the tread's swept footprint
// (engine/host.py ray_rows, local_rays; engine/patch.py), the bed following its vehicle and the floating origin
// (engine/host.py HostSide: its step-by-step path, which the Python engine's lookahead batches reproduce to the
// bit), the pose rows of the vehicles stones hit (engine/impact_pass.py pose_rows) and the step's row of
// engine/stepdata.py (batch_arrays, packed).
#pragma once

#include <array>
#include <optional>
#include <string>
#include <vector>

#include "track.hpp"

namespace rocks {

struct VehicleSpec {
  std::string name;
  bool splash = false;
  double wheelbase = 0, track = 0, tire_radius = 0, slip = 0;
  std::array<double, 5> tread{};  // half width, half contact length, radius, fender angle (rad), flap (-1: none)
};

// motion/vehicles.py VehiclePose: world position (z: the ground), heading, speed, yaw rate, velocity, the
// position relative to the fleet's anchor (computed without world coordinates) and the wheel spin (NaN: rolling)
struct VehiclePose {
  std::array<double, 3> position, velocity, rel;
  double heading, speed, yaw_rate, spin;
};

// one rear tire (motion/vehicles.py RearTires, one row)
struct Tire {
  std::array<double, 3> center, bottom, velocity;
  std::array<double, 2> forward;
  double spin;
  std::array<double, 5> tread;
};

struct HostConfig {
  bool floating = true;
  double ground_z = 0, reach = 0, origin_snap = 64, origin_range = 128, grid_half = 0, store_tile = 1;
  int follow = 0;
  int n_tires = 0;                  // the World's splashing rear tires (0 without splashing)
  std::vector<int> targets;         // the vehicles stones hit (with impacts)
  int ray_fields = 40, hull = 24, hull_vertices = 8, half_w = 19, active = 18, pose_rows = 7;
  int frame_rows = 6, step_bodies = 0;  // the row's layout (engine/stepdata.py packed)
};

// engine/host.py HostState
struct HostState {
  int64_t step_count = 0;
  double time = 0.0;
  std::array<double, 3> anchor{}, origin{}, bed_center{};
  std::array<double, 2> shift{}, bed_rel{}, lead{1.0, 0.0};
  std::vector<VehiclePose> poses;
  std::vector<Tire> tires_prev;
  void set_shift(double sx, double sy);
  std::array<double, 2> local_centre() const { return {bed_rel[0] - shift[0], bed_rel[1] - shift[1]}; }
};

// engine/host.py StepInput, with the device row of engine/stepdata.py
struct StepInput {
  int64_t step;
  double dt;
  std::array<double, 2> centre, move, lead, shift;
  std::optional<std::array<double, 2>> moved;  // the origin's move before this step
  std::vector<double> rays;                    // n_tires x ray_fields (kernels' frame)
  std::vector<double> bodies;                  // pose rows (7 per target) x 2, with impacts
};

class Host {
 public:
  Host(HostConfig cfg, std::vector<VehicleSpec> specs, std::vector<Track> tracks);

  const HostConfig& config() const { return cfg_; }
  std::vector<Track>& tracks() { return tracks_; }
  const std::vector<VehicleSpec>& specs() const { return specs_; }
  // time 0 (HostSide.start)
  void start(HostState& st);
  // one step of dt (HostSide.advance step by step)
  StepInput advance(HostState& st, double dt);
  // the step's float64 row for load_batch (stepdata.batch_arrays + packed), `start` its start time
  std::vector<double> row(const StepInput& s, double start) const;
  // an advance from t0 to t1 starts: the live vehicles' pending poses get their time (drives.bind_to)
  void bind(double t0, double t1);

 private:
  HostConfig cfg_;
  std::vector<VehicleSpec> specs_;
  std::vector<Track> tracks_;
  std::vector<int> splashing_;
  std::array<double, 2> anchor_{};  // the fleet's anchor (Fleet.anchor)

  std::vector<VehiclePose> poses(double t) const;
  std::vector<Tire> rear_tires(const std::vector<VehiclePose>& poses) const;
  std::vector<double> ray_data(const HostState& st, const std::vector<Tire>& prev,
                               const std::vector<Tire>& cur, double dt) const;
  std::vector<double> pose_rows(const std::vector<VehiclePose>& prev, const std::vector<VehiclePose>& cur,
                                const std::array<double, 2>& shift) const;
};

// The convex hull of `points` (XY) counter-clockwise without repeated or collinear vertices: engine/patch.py
// _hull (Andrew's monotone chain), the same cross products and pops.
std::vector<std::array<double, 2>> hull(const std::vector<std::array<double, 2>>& points);

// The smallest prime >= n (engine/world.py next_prime).
int64_t next_prime(int64_t n);

}  // namespace rocks
