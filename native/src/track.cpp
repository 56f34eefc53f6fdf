// Keyframed tracks and recorded drive files (track.hpp): motion/live.py and config/drivefile.py, operation for
// operation. Python evaluates a + b * c + d as ((a + (b * c)) + d); the expressions below keep that order, and the
// library is compiled without floating-point contraction (no fused multiply-adds), so each one rounds as Python's.
#include "track.hpp"

#include <algorithm>
#include <charconv>
#include <fstream>
#include <sstream>

#include "error.hpp"

namespace rocks {

namespace {

const char* const kHeader = "taichi-rocks drive 1";
const char* const kColumns[7] = {"t", "x", "y", "heading", "speed", "yaw_rate", "wheel_spin"};
const uint64_t kMaxBytes = 256ull * 1024 * 1024;

std::string strip(const std::string& s) {
  size_t a = 0, b = s.size();
  while (a < b && std::isspace(static_cast<unsigned char>(s[a]))) a++;
  while (b > a && std::isspace(static_cast<unsigned char>(s[b - 1]))) b--;
  return s.substr(a, b - a);
}

std::vector<std::string> words(const std::string& s) {
  std::istringstream in(s);
  std::vector<std::string> out;
  std::string w;
  while (in >> w) out.push_back(w);
  return out;
}

// The cubic Hermite basis at s and its derivative (motion/live.py _hermite).
void hermite(double s, double a[4], double d[4]) {
  double s2 = s * s, s3 = s * s * s;
  a[0] = 2 * s3 - 3 * s2 + 1;
  a[1] = s3 - 2 * s2 + s;
  a[2] = -2 * s3 + 3 * s2;
  a[3] = s3 - s2;
  d[0] = 6 * s2 - 6 * s;
  d[1] = 3 * s2 - 4 * s + 1;
  d[2] = -6 * s2 + 6 * s;
  d[3] = 3 * s2 - 2 * s;
}

// going straight on from keyframe r at its heading and speed to time t (motion/live.py _straight)
PoseValues straight(const Key& r, double t) {
  double c = std::cos(r.h), s = std::sin(r.h);
  double d = r.v * (t - r.t);
  return {r.x + d * c, r.y + d * s, r.h, r.v, 0.0, r.v * c, r.v * s, r.spin};
}

Key straight_row(const Key& r, double t) {
  PoseValues p = straight(r, t);
  return {t, p.x, p.y, p.h, p.v, p.w, p.spin};
}

// the Hermite interpolation between keyframes r0 and r1 at time t (motion/live.py _between)
PoseValues between(const Key& r0, const Key& r1, double t) {
  double T = r1.t - r0.t;
  double a[4], d[4];
  hermite((t - r0.t) / T, a, d);
  double c0 = std::cos(r0.h), s0 = std::sin(r0.h), c1 = std::cos(r1.h), s1 = std::sin(r1.h);
  double dx = r1.x - r0.x, dy = r1.y - r0.y;
  double x = r0.x + a[2] * dx + T * (a[1] * r0.v * c0 + a[3] * r1.v * c1);
  double y = r0.y + a[2] * dy + T * (a[1] * r0.v * s0 + a[3] * r1.v * s1);
  double vx = (d[2] * dx) / T + d[1] * r0.v * c0 + d[3] * r1.v * c1;
  double vy = (d[2] * dy) / T + d[1] * r0.v * s0 + d[3] * r1.v * s1;
  double dh = wrap_angle(r1.h - r0.h);
  double h = wrap_angle(r0.h + a[2] * dh + T * (a[1] * r0.w + a[3] * r1.w));
  double w = (d[2] * dh) / T + d[1] * r0.w + d[3] * r1.w;
  return {x, y, h, vx * std::cos(h) + vy * std::sin(h), w, vx, vy, r1.spin};
}

// Whether the segment r0 -> r1 is a jump (motion/live.py _jumps). Python's math.hypot may differ from the C
// library's hypot in the last bit; the distance only decides this comparison, which such a bit does not turn
// unless the segment is within 1e-16 of the rule's limit.
bool jumps(const Key& r0, double t1, double x1, double y1, double v1) {
  double T = t1 - r0.t;
  double d = std::hypot(x1 - r0.x, y1 - r0.y);
  return d > 2.0 * std::max(std::fabs(r0.v), std::fabs(v1)) * T + kJumpSlack;
}

bool same(double a, double b) { return a == b || (std::isnan(a) && std::isnan(b)); }

}  // namespace

std::vector<Key> read_drive(const std::string& path) {
  auto bad = [&](int line, const std::string& why) {
    return Error(ROCKS_ERROR_MODULE, path + (line ? ":" + std::to_string(line) : std::string()) + ": " + why);
  };
  std::ifstream f(path, std::ios::binary);
  if (!f) throw bad(0, "cannot read");
  f.seekg(0, std::ios::end);
  if (static_cast<uint64_t>(f.tellg()) > kMaxBytes) throw bad(0, "larger than 256 MB: not a drive");
  f.seekg(0);
  std::string text((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  if (text.compare(0, 3, "\xEF\xBB\xBF") == 0) text.erase(0, 3);
  std::vector<std::string> lines;
  {
    std::string cur;
    for (size_t i = 0; i < text.size(); i++) {
      char c = text[i];
      if (c == '\n' || c == '\r') {
        lines.push_back(cur);
        cur.clear();
        if (c == '\r' && i + 1 < text.size() && text[i + 1] == '\n') i++;
      } else {
        cur += c;
      }
    }
    if (!cur.empty()) lines.push_back(cur);
  }
  if (lines.empty() || strip(lines[0]) != kHeader)
    throw bad(1, std::string("expected the header '") + kHeader + "'");
  std::vector<Key> rows;
  bool columns = false;
  for (size_t n = 1; n < lines.size(); n++) {
    int ln = static_cast<int>(n) + 1;
    std::string line = strip(lines[n]);
    if (line.empty() || line[0] == '#') continue;
    auto ws = words(line);
    if (!columns) {
      bool ok = ws.size() == 7;
      for (size_t k = 0; ok && k < 7; k++) ok = ws[k] == kColumns[k];
      if (!ok) throw bad(ln, "expected the columns 't x y heading speed yaw_rate wheel_spin'");
      columns = true;
      continue;
    }
    if (ws.size() != 7) throw bad(ln, "expected 7 values (t x y heading speed yaw_rate wheel_spin), got " +
                                      std::to_string(ws.size()));
    double v[7];
    for (int k = 0; k < 7; k++) {
      const std::string& w = ws[k];
      if (k == 6 && w == "-") {
        v[k] = std::numeric_limits<double>::quiet_NaN();
        continue;
      }
      const char* first = w.data();
      const char* last = w.data() + w.size();
      if (first != last && *first == '+') first++;
      auto r = std::from_chars(first, last, v[k]);
      if (r.ec != std::errc() || r.ptr != last) throw bad(ln, std::string(kColumns[k]) + ": expected a number");
      if (!std::isfinite(v[k])) throw bad(ln, std::string(kColumns[k]) + ": must be finite");
    }
    if (v[0] < 0.0) throw bad(ln, "t: must be >= 0");
    if (!rows.empty() && !(v[0] > rows.back().t)) throw bad(ln, "t: times must increase");
    rows.push_back({v[0], v[1], v[2], v[3], v[4], v[5], v[6]});
  }
  if (!columns) throw bad(0, "no column line ('t x y heading speed yaw_rate wheel_spin')");
  if (rows.empty()) throw bad(0, "no poses (at least one row after the column line)");
  return rows;
}

Track::Track(std::vector<Key> rows, bool live) : rows_(std::move(rows)), live_(live) {
  if (rows_.empty()) throw Error(ROCKS_ERROR_MODULE, "a track needs at least one pose");
  kind_.push_back(kHermite);
  for (size_t k = 1; k < rows_.size(); k++) {
    const Key& r0 = rows_[k - 1];
    const Key& r1 = rows_[k];
    Key s = straight_row(r0, r1.t);
    bool st = same(s.t, r1.t) && same(s.x, r1.x) && same(s.y, r1.y) && same(s.h, r1.h) && same(s.v, r1.v) &&
              same(s.w, r1.w) && same(s.spin, r1.spin);
    kind_.push_back(st ? kStraight : jumps(r0, r1.t, r1.x, r1.y, r1.v) ? kJump : kHermite);
  }
  ax_ = rows_[0].x;
  ay_ = rows_[0].y;
  horizon_ = live_ ? rows_.back().t : std::numeric_limits<double>::infinity();
}

PoseValues Track::at_key(size_t k) const {
  const Key& r = rows_[k];
  return {r.x, r.y, r.h, r.v, r.w, r.v * std::cos(r.h), r.v * std::sin(r.h), r.spin};
}

PoseValues Track::pose_values(double t) const {
  // bisect_left over the keyframes' times
  size_t k = std::lower_bound(rows_.begin(), rows_.end(), t, [](const Key& r, double v) { return r.t < v; }) -
             rows_.begin();
  size_t n = rows_.size();
  if (k < n && rows_[k].t - t <= clock_tolerance(rows_[k].t)) return at_key(k);
  if (k > 0 && t - rows_[k - 1].t <= clock_tolerance(rows_[k - 1].t)) return at_key(k - 1);
  if (k == 0 || k == n) return straight(rows_[k == 0 ? 0 : n - 1], t);
  const Key& r0 = rows_[k - 1];
  const Key& r1 = rows_[k];
  if (kind_[k] == kJump) return straight(r1, t);
  if (kind_[k] == kStraight) return straight(r0, t);
  return between(r0, r1, t);
}

Key Track::keyframe(const DrivePose& p, double t) const {
  const Key& r0 = rows_.back();
  double T = t - r0.t;
  double v_guess = std::isnan(p.v) ? r0.v : p.v;
  bool jump = jumps(r0, t, p.x, p.y, v_guess);
  double v = p.v, w = p.w;
  if (std::isnan(v))
    v = jump ? r0.v : ((p.x - r0.x) * std::cos(p.h) + (p.y - r0.y) * std::sin(p.h)) / T;
  if (std::isnan(w)) w = jump ? 0.0 : wrap_angle(p.h - r0.h) / T;
  return {t, p.x, p.y, p.h, v, w, p.spin};
}

void Track::append(const Key& row) {
  const Key& r0 = rows_.back();
  Key s = straight_row(r0, row.t);
  bool st = same(s.t, row.t) && same(s.x, row.x) && same(s.y, row.y) && same(s.h, row.h) && same(s.v, row.v) &&
            same(s.w, row.w) && same(s.spin, row.spin);
  kind_.push_back(st ? kStraight : jumps(r0, row.t, row.x, row.y, row.v) ? kJump : kHermite);
  rows_.push_back(row);
}

void Track::truncate(double t) {
  // bisect_right over the times, keeping the first keyframe
  size_t k = std::upper_bound(rows_.begin(), rows_.end(), t, [](double v, const Key& r) { return v < r.t; }) -
             rows_.begin();
  k = std::max<size_t>(1, k);
  rows_.resize(k);
  kind_.resize(k);
}

void Track::bind(double t0, double t1) {
  if (pending_) {
    DrivePose p = *pending_;
    pending_.reset();
    double tol = clock_tolerance(t0);
    PoseValues at = pose_values(t0);  // where it is: straight on, or on its way to a pose
    truncate(t0 + tol);
    if (rows_.back().t < t0 - tol) append({t0, at.x, at.y, at.h, at.v, at.w, at.spin});
    append(keyframe(p, t1));
  }
  horizon_ = t1;
}

}  // namespace rocks
