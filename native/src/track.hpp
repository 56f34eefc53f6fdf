// A vehicle's keyframed track: the recorded drives a module replays and the live vehicles rocks_drive steers, with
// the pose at any time between keyframes. A port of the Python engine's motion/live.py (LivePath) with the same
// floating-point operations in the same order (the module docstring there states the interpolation), and the
// reader of the recorded drive format of config/drivefile.py (docs/drives.md).
#pragma once

#include <cmath>
#include <limits>
#include <optional>
#include <string>
#include <vector>

namespace rocks {

// one keyframe: time (s), world x, y (m), heading (rad), speed (m/s), yaw rate (rad/s), wheel spin (rad/s; NaN:
// rolling)
struct Key {
  double t, x, y, h, v, w, spin;
};

// what motion/live.py's pose_values returns: x, y (world), heading, speed, yaw rate, velocity x, y, wheel spin
struct PoseValues {
  double x, y, h, v, w, vx, vy, spin;
};

// a pose the game asked for (rocks_drive), not yet bound to a time; NaN speed / yaw rate / spin: not given
struct DrivePose {
  double x, y, h, v, w, spin;
};

constexpr double kTwoPi = 2.0 * 3.141592653589793;
constexpr double kPi = 3.141592653589793;
constexpr double kJumpSlack = 1.0;  // m (motion/live.py JUMP_SLACK)

// Python's clock tolerance at time t: 1e-9 max(1, |t|) (motion/live.py clock_tolerance)
inline double clock_tolerance(double t) { return 1e-9 * std::max(1.0, std::fabs(t)); }

// an angle wrapped to (-pi, pi] (motion/paths.py _wrap: IEEE remainder, exact)
inline double wrap_angle(double a) {
  double r = std::remainder(a, kTwoPi);
  return r <= -kPi ? r + kTwoPi : r;
}

// The rows of the recorded drive file `path` (docs/drives.md); throws Error(ROCKS_ERROR_MODULE) naming the file
// and the line, as config/drivefile.py read_drive refuses the same files.
std::vector<Key> read_drive(const std::string& path);

class Track {
 public:
  Track(std::vector<Key> rows, bool live);

  bool live() const { return live_; }
  double anchor_x() const { return ax_; }
  double anchor_y() const { return ay_; }
  double horizon() const { return horizon_; }
  const std::vector<Key>& rows() const { return rows_; }

  PoseValues pose_values(double t) const;
  // the pending pose of the next advance (a later one replaces it)
  void set_pending(const DrivePose& p) { pending_ = p; }
  // an advance from clock t0 to t1 starts: the pending pose becomes the keyframe at t1 (LivePath.bind)
  void bind(double t0, double t1);

 private:
  enum Segment { kHermite, kJump, kStraight };
  std::vector<Key> rows_;
  std::vector<int> kind_;
  double ax_ = 0.0, ay_ = 0.0;
  bool live_;
  double horizon_;
  std::optional<DrivePose> pending_;

  PoseValues at_key(size_t k) const;
  Key keyframe(const DrivePose& p, double t) const;
  void append(const Key& row);
  void truncate(double t);
};

}  // namespace rocks
