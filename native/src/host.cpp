// The host side of a step (host.hpp), operation for operation as the Python engine computes it. Where NumPy is
// involved the C equivalents of its routines are used: np.cos, np.sin, np.hypot are the C library's functions,
// np.round is round-half-even (std::nearbyint in the default rounding mode), and a dot product of two 2-vectors
// (`vel @ fwd` in motion/vehicles.py) is BLAS's ddot, which on x86-64 computes fma(x1, y1, x0 * y0).
#include "host.hpp"

#include <algorithm>
#include <cmath>

#include "error.hpp"

namespace rocks {

void HostState::set_shift(double sx, double sy) {
  shift = {sx, sy};
  origin = anchor;
  origin[0] += sx;
  origin[1] += sy;
}

Host::Host(HostConfig cfg, std::vector<VehicleSpec> specs, std::vector<Track> tracks)
    : cfg_(std::move(cfg)), specs_(std::move(specs)), tracks_(std::move(tracks)) {
  if (specs_.size() != tracks_.size() || specs_.empty())
    throw Error(ROCKS_ERROR_MODULE, "the vehicles and their drives do not match");
  for (size_t i = 0; i < specs_.size(); i++)
    if (specs_[i].splash) splashing_.push_back(static_cast<int>(i));
  if (cfg_.n_tires != 0 && cfg_.n_tires != 2 * static_cast<int>(splashing_.size()))
    throw Error(ROCKS_ERROR_MODULE, "the module's tire count does not match its splashing vehicles");
  if (cfg_.follow < 0 || cfg_.follow >= static_cast<int>(specs_.size()))
    throw Error(ROCKS_ERROR_MODULE, "the module's followed vehicle is not one of its vehicles");
  for (int t : cfg_.targets)
    if (t < 0 || t >= static_cast<int>(specs_.size()))
      throw Error(ROCKS_ERROR_MODULE, "a vehicle stones hit is not one of the module's vehicles");
}

// motion/vehicles.py Fleet.poses: each track's pose at t, its position relative to the fleet's anchor computed
// as (track anchor - fleet anchor) + (position - track anchor) (Fleet._relative)
std::vector<VehiclePose> Host::poses(double t) const {
  std::vector<VehiclePose> out;
  out.reserve(tracks_.size());
  double gz = cfg_.ground_z;
  for (const Track& tr : tracks_) {
    PoseValues p = tr.pose_values(t);
    double lx = p.x - tr.anchor_x(), ly = p.y - tr.anchor_y();
    VehiclePose v;
    v.position = {p.x, p.y, gz};
    v.heading = p.h;
    v.speed = p.v;
    v.yaw_rate = p.w;
    v.velocity = {p.vx, p.vy, 0.0};
    v.rel = {(tr.anchor_x() - anchor_[0]) + lx, (tr.anchor_y() - anchor_[1]) + ly, gz};
    v.spin = p.spin;
    out.push_back(v);
  }
  return out;
}

// motion/vehicles.py Fleet.rear_tires(poses, relative=True)
std::vector<Tire> Host::rear_tires(const std::vector<VehiclePose>& poses) const {
  std::vector<Tire> out;
  for (int i : splashing_) {
    const VehicleSpec& spec = specs_[i];
    const VehiclePose& pose = poses[i];
    double c = std::cos(pose.heading), s = std::sin(pose.heading);
    for (double side : {1.0, -1.0}) {
      double bx = -0.5 * spec.wheelbase, by = side * 0.5 * spec.track;
      double r0 = c * bx - s * by, r1 = s * bx + c * by;
      double vel0 = pose.velocity[0] + pose.yaw_rate * -r1;
      double vel1 = pose.velocity[1] + pose.yaw_rate * r0;
      Tire t;
      t.center = {pose.rel[0] + r0, pose.rel[1] + r1, cfg_.ground_z + spec.tire_radius};
      t.bottom = {t.center[0], t.center[1], cfg_.ground_z};
      t.velocity = {vel0, vel1, 0.0};
      t.forward = {c, s};
      t.spin = std::fma(vel1, s, vel0 * c) * (1.0 + spec.slip);  // float(vel @ fwd) * (1 + slip)
      if (!std::isnan(pose.spin)) t.spin = pose.spin * spec.tire_radius;
      t.tread = spec.tread;
      out.push_back(t);
    }
  }
  return out;
}

std::vector<std::array<double, 2>> hull(const std::vector<std::array<double, 2>>& points) {
  // sorted({(x, y) ...}): equal points (0.0 == -0.0 too) keep the first seen, then a sort by (x, y)
  std::vector<std::array<double, 2>> pts;
  for (const auto& p : points) {
    bool seen = false;
    for (const auto& q : pts) seen = seen || (q[0] == p[0] && q[1] == p[1]);
    if (!seen) pts.push_back(p);
  }
  std::stable_sort(pts.begin(), pts.end(), [](const auto& a, const auto& b) {
    return a[0] < b[0] || (a[0] == b[0] && a[1] < b[1]);
  });
  if (pts.size() <= 2) return pts;
  auto cross = [](const auto& o, const auto& a, const auto& b) {
    return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]);
  };
  std::vector<std::array<double, 2>> lower, upper;
  for (const auto& p : pts) {
    while (lower.size() >= 2 && cross(lower[lower.size() - 2], lower.back(), p) <= 0) lower.pop_back();
    lower.push_back(p);
  }
  for (auto it = pts.rbegin(); it != pts.rend(); ++it) {
    while (upper.size() >= 2 && cross(upper[upper.size() - 2], upper.back(), *it) <= 0) upper.pop_back();
    upper.push_back(*it);
  }
  std::vector<std::array<double, 2>> out(lower.begin(), lower.end() - 1);
  out.insert(out.end(), upper.begin(), upper.end() - 1);
  return out;
}

namespace {

// engine/patch.py footprint_corners for one tire: b + sl hl f + sw hw l, l = (-f_y, f_x)
void corners(const std::array<double, 3>& b, const std::array<double, 2>& f, double hw, double hl,
             std::vector<std::array<double, 2>>& out) {
  const double signs[4][2] = {{1, 1}, {-1, 1}, {-1, -1}, {1, -1}};
  double lx = -f[1], ly = f[0];
  for (const auto& sg : signs) {
    double a = sg[0] * hl, w = sg[1] * hw;
    out.push_back({b[0] + a * f[0] + w * lx, b[1] + a * f[1] + w * ly});
  }
}

double norm3(const std::array<double, 3>& v) { return std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]); }

}  // namespace

// engine/host.py ray_rows + local_rays (step by step: HostSide.ray_data) for the tires prev -> cur
std::vector<double> Host::ray_data(const HostState& st, const std::vector<Tire>& prev, const std::vector<Tire>& cur,
                                   double dt) const {
  const int F = cfg_.ray_fields;
  size_t n = cur.size();
  std::vector<double> rows(n * F, 0.0);
  std::array<double, 2> lc = st.local_centre();
  std::array<double, 3> park = {lc[0], lc[1], st.bed_center[2] - st.origin[2] + 1000.0};
  for (size_t t = 0; t < n; t++) {
    const Tire& a = prev[t];
    const Tire& b = cur[t];
    double* r = &rows[t * F];
    // a tire that moved much farther than its speed allows did not sweep the ground in between
    std::array<double, 3> d = {b.center[0] - a.center[0], b.center[1] - a.center[1], b.center[2] - a.center[2]};
    double moved = norm3(d);
    double speed = std::max(norm3(b.velocity), norm3(a.velocity));
    bool jumped = moved > 2.0 * speed * dt + 0.05;
    const Tire& p = jumped ? b : a;
    for (int k = 0; k < 3; k++) {
      r[0 + k] = p.center[k];
      r[3 + k] = p.bottom[k];
      r[6 + k] = b.center[k];
      r[9 + k] = b.bottom[k];
      r[12 + k] = b.velocity[k];
    }
    r[15] = b.forward[0];
    r[16] = b.forward[1];
    r[17] = b.spin;
    // the tread (engine/patch.py tread_columns): sizes, fender, flap, the swept footprint's hull
    for (int k = 0; k < 5; k++) r[cfg_.half_w + k] = b.tread[k];
    std::vector<std::array<double, 2>> pts;
    corners(jumped ? b.bottom : a.bottom, jumped ? b.forward : a.forward, b.tread[0], b.tread[1], pts);
    corners(b.bottom, b.forward, b.tread[0], b.tread[1], pts);
    auto h = hull(pts);
    for (int k = 0; k < cfg_.hull_vertices; k++) {
      const auto& v = h[std::min<size_t>(k, h.size() - 1)];  // padded by repeating the last vertex
      r[cfg_.hull + 2 * k] = v[0];
      r[cfg_.hull + 2 * k + 1] = v[1];
    }
    bool far = std::hypot(b.center[0] - st.bed_rel[0], b.center[1] - st.bed_rel[1]) > cfg_.reach;
    r[cfg_.active] = far ? 0.0 : 1.0;
    // into the kernels' frame (local_rays): positions minus the shift; far tires parked high above the bed
    if (far) {
      for (int k = 0; k < 12; k++) r[k] = park[k % 3];
      for (int k = cfg_.hull; k < F; k++) r[k] = park[(k - cfg_.hull) % 2];
      r[17] = 0.0;
    } else {
      for (int k = 0; k < 12; k += 3) {
        r[k] -= st.shift[0];
        r[k + 1] -= st.shift[1];
        r[k + 2] -= 0.0;
      }
      for (int k = cfg_.hull; k < F; k += 2) {
        r[k] -= st.shift[0];
        r[k + 1] -= st.shift[1];
      }
    }
  }
  return rows;
}

// engine/impact_pass.py pose_rows: per target, its centre at the step's start and end (kernels' frame), the
// (cos, sin) of its headings, its velocities and its yaw rates
std::vector<double> Host::pose_rows(const std::vector<VehiclePose>& prev, const std::vector<VehiclePose>& cur,
                                    const std::array<double, 2>& shift) const {
  std::vector<double> out;
  for (int i : cfg_.targets) {
    const VehiclePose& a = prev[i];
    const VehiclePose& b = cur[i];
    double rows[7][2] = {{a.rel[0] - shift[0], a.rel[1] - shift[1]},
                         {b.rel[0] - shift[0], b.rel[1] - shift[1]},
                         {std::cos(a.heading), std::sin(a.heading)},
                         {std::cos(b.heading), std::sin(b.heading)},
                         {a.velocity[0], a.velocity[1]},
                         {b.velocity[0], b.velocity[1]},
                         {a.yaw_rate, b.yaw_rate}};
    for (auto& r : rows) out.insert(out.end(), r, r + 2);
  }
  return out;
}

void Host::start(HostState& st) {
  st.step_count = 0;
  st.time = 0.0;
  st.anchor = {0.0, 0.0, 0.0};
  if (cfg_.floating) {
    const Track& f = tracks_[cfg_.follow];
    st.anchor[0] = f.anchor_x();
    st.anchor[1] = f.anchor_y();
  }
  anchor_ = {st.anchor[0], st.anchor[1]};
  st.poses = poses(0.0);
  const VehiclePose& c = st.poses[cfg_.follow];
  st.bed_center = {c.position[0], c.position[1], cfg_.ground_z};
  st.bed_rel = {c.rel[0], c.rel[1]};
  if (cfg_.floating)
    st.set_shift(std::nearbyint(st.bed_rel[0] / cfg_.origin_snap) * cfg_.origin_snap,
                 std::nearbyint(st.bed_rel[1] / cfg_.origin_snap) * cfg_.origin_snap);
  else
    st.set_shift(0.0, 0.0);
  st.lead = {std::cos(c.heading), std::sin(c.heading)};
  st.tires_prev = rear_tires(st.poses);
}

void Host::bind(double t0, double t1) {
  bool any = false;
  for (const Track& tr : tracks_) any = any || tr.live();
  if (!any || !(t1 - t0 > clock_tolerance(t1))) return;
  for (Track& tr : tracks_)
    if (tr.live()) tr.bind(t0, t1);
}

StepInput Host::advance(HostState& st, double dt) {
  st.step_count += 1;
  st.time += dt;
  std::vector<VehiclePose> now = poses(st.time);
  // the bed follows its vehicle (HostSide._follow)
  const VehiclePose& f = now[cfg_.follow];
  StepInput s;
  s.move = {f.rel[0] - st.bed_rel[0], f.rel[1] - st.bed_rel[1]};
  st.bed_center = {f.position[0], f.position[1], st.bed_center[2]};
  st.bed_rel = {f.rel[0], f.rel[1]};
  double speed = std::hypot(f.velocity[0], f.velocity[1]);
  if (speed > 1e-9) st.lead = {f.velocity[0] / speed, f.velocity[1] / speed};
  // the floating origin (HostSide._keep_origin_near)
  if (cfg_.floating && std::max(std::fabs(st.bed_rel[0] - st.shift[0]), std::fabs(st.bed_rel[1] - st.shift[1])) >
                           cfg_.origin_range) {
    double nx = std::nearbyint(st.bed_rel[0] / cfg_.origin_snap) * cfg_.origin_snap;
    double ny = std::nearbyint(st.bed_rel[1] / cfg_.origin_snap) * cfg_.origin_snap;
    s.moved = std::array<double, 2>{nx - st.shift[0], ny - st.shift[1]};
    st.set_shift(nx, ny);
  }
  std::vector<Tire> tires_now = rear_tires(now);
  if (cfg_.n_tires) s.rays = ray_data(st, st.tires_prev, tires_now, dt);
  st.tires_prev = std::move(tires_now);
  if (!cfg_.targets.empty()) s.bodies = pose_rows(st.poses, now, st.shift);
  st.poses = std::move(now);
  s.step = st.step_count;
  s.dt = dt;
  s.centre = st.local_centre();
  s.lead = st.lead;
  s.shift = st.shift;
  return s;
}

std::vector<double> Host::row(const StepInput& s, double start) const {
  std::vector<double> out;
  out.reserve(2 * cfg_.frame_rows + cfg_.n_tires * cfg_.ray_fields + 2 * cfg_.step_bodies);
  // the frame rows (engine/world.py CENTRE, MOVE, LEAD, GRID, TILES, CLOCK)
  double frame[] = {s.centre[0], s.centre[1], s.move[0], s.move[1], s.lead[0], s.lead[1],
                    s.centre[0] - cfg_.grid_half, s.centre[1] - cfg_.grid_half,
                    s.shift[0] / cfg_.store_tile, s.shift[1] / cfg_.store_tile, s.dt, start};
  out.insert(out.end(), frame, frame + 12);
  if (cfg_.n_tires) out.insert(out.end(), s.rays.begin(), s.rays.end());
  if (cfg_.step_bodies) {
    size_t at = out.size();
    out.resize(at + 2 * cfg_.step_bodies, 0.0);
    std::copy(s.bodies.begin(), s.bodies.end(), out.begin() + at);
  }
  return out;
}

int64_t next_prime(int64_t n) {
  n = std::max<int64_t>(2, n);
  auto prime = [](int64_t m) {
    if (m < 4) return m >= 2;
    if (m % 2 == 0) return false;
    for (int64_t f = 3; f * f <= m; f += 2)
      if (m % f == 0) return false;
    return true;
  };
  while (!prime(n)) n++;
  return n;
}

}  // namespace rocks
