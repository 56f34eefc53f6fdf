// The C API of rocks.h: a module opened on Taichi's runtime, stepped as the Python engine steps it
// (engine/simulation.py advance_to and _step, engine/steppers.py ActiveStepper.step and _fit, engine/impact_pass.py
// ImpactLog, engine/events.py EventBuffer.drain, engine/simulation.py changes), with no coasting: the Python
// engine's coasting gives the bits of stepping, so a module steps every step.
#include "rocks.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <limits>
#include <memory>
#include <new>
#include <sstream>

#include "device.hpp"
#include "error.hpp"
#include "host.hpp"
#include "json.hpp"

#ifndef ROCKS_TAICHI_RUNTIME_DIR
#define ROCKS_TAICHI_RUNTIME_DIR ""
#endif

using rocks::Error;

namespace {

const char* const kFormat = "taichi-rocks module 1";
const int64_t kStepLimit = 2147483647;  // steps the kernels count (an i32; engine/arguments.py STEP_LIMIT)

struct Field {
  std::string group;
  int64_t offset = 0, row = 0;
  uint32_t element(int64_t entry) const {  // the group element where entry `entry` starts
    return static_cast<uint32_t>(row ? (offset + entry) * row : offset + entry);
  }
};

std::string read_text(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw Error(ROCKS_ERROR_MODULE, path + ": cannot be read (not a module folder?)");
  std::ostringstream s;
  s << f.rdbuf();
  return s.str();
}

}  // namespace

struct RocksSim {
  std::string error;
  std::string folder;
  rocks::Json manifest;
  rocks::Device dev;
  std::unique_ptr<rocks::Host> host;
  rocks::HostState st;
  std::vector<std::string> names;
  bool broken = false;

  // the engine's facts (manifest.json "host")
  int64_t n_rocks = 0;
  double dt = 0;
  bool moves = false, splash = false, impacts = false, spin = false, drawn = false;
  bool check_all = true;
  int64_t table_size = 0, table_min = 0, table_every = 32;
  double table_load = 1.5;
  bool table_auto = false;
  int ipar_n_rocks = 0, ipar_table = 0;
  std::map<std::string, Field> fields;

  // events (engine/impact_pass.py ImpactLog, engine/events.py EventBuffer)
  int ev_capacity = 0, ev_drain_every = 64, n_int = 0, n_real = 0;
  double ref_span = 1.0;
  int64_t keep = 1 << 20;
  double t_ref = 0.0;
  bool t_ref_written = false;
  double t_ref_written_value = 0.0;
  int64_t dropped = 0, lost = 0, handed_out = 0;
  std::vector<std::vector<RocksImpact>> chunks;
  int64_t kept = 0;
  std::map<std::string, std::pair<bool, int>> columns;  // name -> (int, first column)
  std::vector<int32_t> ev_ints;
  std::vector<double> ev_reals;
  std::vector<RocksImpact> impacts_out;

  // changes()
  std::vector<double> rows;
  std::vector<int32_t> ids;
  std::vector<double> positions, orientations;
  std::vector<int8_t> phase;

  void load(const std::string& dir);
  void step(double h);
  void shift_origin(const std::array<double, 2>& d);
  void fit();
  void drain(double t_now);
  std::vector<RocksImpact> take_all();
  void changes(RocksChanges* out);
};

void RocksSim::load(const std::string& dir) {
  folder = dir;
  std::string mpath = dir + "/manifest.json";
  manifest = rocks::Json::parse(read_text(mpath), "manifest.json");
  const rocks::Json& m = manifest;
  if (!m.has("format") || m["format"].kind() != rocks::Json::String || m["format"].string() != kFormat)
    throw Error(ROCKS_ERROR_MODULE, mpath + ": not a module of this library's format (\"" + kFormat + "\")");
  uint32_t v = ti_get_version();
  std::string have = std::to_string(v / 1000000) + "." + std::to_string(v / 1000 % 1000) + ".";
  if (m["taichi"].string().compare(0, have.size(), have) != 0)
    throw Error(ROCKS_ERROR_MODULE, mpath + ": a module of Taichi " + m["taichi"].string() +
                                        ", this library runs Taichi " + have + "x (make the module again)");
  const rocks::Json& h = m["host"];
  n_rocks = m["rocks"].integer();
  dt = h["dt"].number();
  if (!(dt > 0.0) || !std::isfinite(dt)) throw Error(ROCKS_ERROR_MODULE, mpath + ": host.dt: must be > 0");
  moves = h["moves"].boolean();
  splash = h["splash"].boolean();
  impacts = h["impacts"].boolean();
  spin = h["spin"].boolean();
  drawn = h["drawn"].boolean();
  table_size = h["table"]["size"].integer();
  table_auto = h["table"]["auto"].boolean();
  table_min = h["table"]["min"].integer();
  table_load = h["table"]["load"].number();
  table_every = h["table"]["every"].integer();
  if (table_every < 1) throw Error(ROCKS_ERROR_MODULE, mpath + ": host.table.every: must be >= 1");
  ipar_n_rocks = static_cast<int>(h["ipar"]["n_rocks"].integer());
  ipar_table = static_cast<int>(h["ipar"]["table"].integer());
  const rocks::Json& fs = m["fields"];
  for (size_t i = 0; i < fs.size(); i++) {
    Field f{fs[i]["group"].string(), fs[i]["offset"].integer(), fs[i]["row"].integer()};
    fields[fs[i]["name"].string()] = f;
  }
  for (const char* need : {"ipar", "launches", "recycles", "origin_move"})
    if (!fields.count(need)) throw Error(ROCKS_ERROR_MODULE, mpath + ": fields: no field " + need);
  if (impacts) {
    const rocks::Json& e = h["events"];
    ev_capacity = static_cast<int>(e["capacity"].integer());
    ev_drain_every = static_cast<int>(e["drain_every"].integer());
    ref_span = e["ref_span"].number();
    keep = e["keep"].integer();
    n_int = static_cast<int>(e["ints"].integer());
    n_real = static_cast<int>(e["reals"].integer());
    if (ev_capacity < 1 || ev_drain_every < 1 || n_int < 1 || n_real < 1)
      throw Error(ROCKS_ERROR_MODULE, mpath + ": host.events: out of range");
    for (size_t i = 0; i < e["columns"].size(); i++) {
      const rocks::Json& c = e["columns"][i];
      columns[c["name"].string()] = {c["int"].boolean(), static_cast<int>(c["column"].integer())};
    }
    for (const char* need : {"time", "step", "vehicle", "part", "damage", "point", "normal", "speed",
                             "normal_speed", "normal_momentum", "energy", "radius", "rock", "thrower"})
      if (!columns.count(need)) throw Error(ROCKS_ERROR_MODULE, mpath + ": host.events: no column " + need);
    if (!fields.count("body_rows")) throw Error(ROCKS_ERROR_MODULE, mpath + ": fields: no field body_rows");
  }

  // the host side: its constants, the vehicles and their drives
  rocks::HostConfig cfg;
  cfg.floating = h["floating"].boolean();
  cfg.ground_z = h["ground_z"].number();
  cfg.reach = h["reach"].number();
  cfg.origin_snap = h["origin_snap"].number();
  cfg.origin_range = h["origin_range"].number();
  cfg.grid_half = h["grid_half"].number();
  cfg.store_tile = h["store_tile"].number();
  cfg.follow = static_cast<int>(h["follow"].integer());
  cfg.n_tires = static_cast<int>(h["n_tires"].integer());
  for (size_t i = 0; i < h["targets"].size(); i++) cfg.targets.push_back(static_cast<int>(h["targets"][i].integer()));
  cfg.ray_fields = static_cast<int>(h["ray_fields"].integer());
  cfg.hull = static_cast<int>(h["ray"]["hull"].integer());
  cfg.half_w = static_cast<int>(h["ray"]["half_w"].integer());
  cfg.active = static_cast<int>(h["ray"]["active"].integer());
  cfg.hull_vertices = static_cast<int>(h["hull_vertices"].integer());
  cfg.pose_rows = static_cast<int>(h["pose_rows"].integer());
  cfg.frame_rows = static_cast<int>(h["frame_rows"].integer());
  cfg.step_bodies = static_cast<int>(h["step_bodies"].integer());
  // the layout this library writes its rays and rows in (engine/world.py): a module of another one is refused
  const rocks::Json& r = h["ray"];
  if (cfg.ray_fields != cfg.hull + 2 * cfg.hull_vertices || r["a0"].integer() != 0 || r["b0"].integer() != 3 ||
      r["a1"].integer() != 6 || r["b1"].integer() != 9 || r["vel"].integer() != 12 || r["fwd"].integer() != 15 ||
      r["spin"].integer() != 17 || cfg.active != 18 || cfg.half_w != 19 || cfg.frame_rows != 6 ||
      cfg.pose_rows != 7 || h["frame"]["clock"].integer() != 5)
    throw Error(ROCKS_ERROR_MODULE, mpath + ": host: a ray or row layout this library does not write");
  if (static_cast<int>(cfg.targets.size()) * cfg.pose_rows > cfg.step_bodies && impacts)
    throw Error(ROCKS_ERROR_MODULE, mpath + ": host.step_bodies: too few rows for the vehicles hit");
  std::vector<rocks::VehicleSpec> specs;
  std::vector<rocks::Track> tracks;
  const rocks::Json& vs = m["vehicles"];
  for (size_t i = 0; i < vs.size(); i++) {
    const rocks::Json& vj = vs[i];
    rocks::VehicleSpec s;
    s.name = vj["name"].string();
    s.splash = vj["splash"].boolean();
    s.wheelbase = vj["wheelbase"].number();
    s.track = vj["track"].number();
    s.tire_radius = vj["tire_radius"].number();
    s.slip = vj["slip"].number();
    auto tread = vj["tread"].numbers();
    if (tread.size() != 5) throw Error(ROCKS_ERROR_MODULE, vj["tread"].path() + ": expected 5 numbers");
    std::copy(tread.begin(), tread.end(), s.tread.begin());
    const std::string& kind = vj["kind"].string();
    if (kind != "live" && kind != "recorded")
      throw Error(ROCKS_ERROR_MODULE, vj["kind"].path() + ": expected \"live\" or \"recorded\", got " + kind);
    tracks.emplace_back(rocks::read_drive(dir + "/" + vj["drive"].string()), kind == "live");
    names.push_back(s.name);
    specs.push_back(s);
  }
  host = std::make_unique<rocks::Host>(cfg, specs, std::move(tracks));
  host->start(st);
  // the module was made from the same start: the anchor and the shift agree, or it belongs to other drives
  auto anchor = h["start"]["anchor"].numbers();
  auto shift = h["start"]["shift"].numbers();
  if (anchor.size() != 3 || shift.size() != 2 || anchor[0] != st.anchor[0] || anchor[1] != st.anchor[1] ||
      shift[0] != st.shift[0] || shift[1] != st.shift[1])
    throw Error(ROCKS_ERROR_MODULE, mpath + ": host.start: the drives do not start where the module's bed does");

  // the device: Taichi's runtime, the kernels, the World's buffers
  if (m["arch"].string() == "x64" && ROCKS_TAICHI_RUNTIME_DIR[0])
    setenv("TI_LIB_DIR", ROCKS_TAICHI_RUNTIME_DIR, 0);  // the x64 runtime's bitcode, unless the environment names it
  dev.open(m["arch"].string(), dir, m);
}

void RocksSim::shift_origin(const std::array<double, 2>& d) {
  // engine/steppers.py Stepper.shift_origin: the move and the origin before and after it into origin_move
  double v[6] = {d[0], d[1], st.anchor[0] + (st.shift[0] - d[0]), st.anchor[1] + (st.shift[1] - d[1]),
                 st.origin[0], st.origin[1]};
  dev.write_f64(fields["origin_move"].element(0), 6, v);
  dev.move_origin();
}

void RocksSim::fit() {
  // engine/steppers.py ActiveStepper._fit: the hash's slots in use, a prime about 1.5 times the active list
  if (!(splash && table_auto)) return;
  int32_t active = 0;
  dev.read_i32(fields["ipar"].element(ipar_n_rocks), 1, &active);
  int64_t want = rocks::next_prime(std::max<int64_t>(table_min, static_cast<int64_t>(table_load * active)));
  int32_t slots = static_cast<int32_t>(std::min(want, table_size));
  dev.write_i32(fields["ipar"].element(ipar_table), 1, &slots);
}

void RocksSim::step(double h) {
  rocks::StepInput s = host->advance(st, h);
  if (s.moved && n_rocks) shift_origin(*s.moved);
  if (moves) {
    dev.load_batch(host->row(s, impacts ? st.time - s.dt : 0.0));
    if (impacts && (!t_ref_written || t_ref_written_value != t_ref)) {  // engine/stepdata.py put_t_ref
      double row[2] = {0.0, t_ref};
      dev.write_f64(fields["body_rows"].element(0), 2, row);
      t_ref_written = true;
      t_ref_written_value = t_ref;
    }
    int step = static_cast<int>(s.step);
    dev.active_step(0, step, check_all ? 1 : 0);
    dev.active_finish(0, step);
    if (check_all || s.step % table_every == 0) fit();
    check_all = false;
  }
  if (impacts && st.step_count % ev_drain_every == 0) drain(st.time);
}

void RocksSim::drain(double t_now) {
  int64_t appended = dev.take_events(ev_ints, ev_reals, n_int, n_real, ev_capacity);
  if (appended == 0) {  // most drains: nothing, and the reference time stays unless it lags REF_SPAN behind
    if (std::fabs(t_now - t_ref) > ref_span) t_ref = t_now;
    return;
  }
  int64_t n = std::min<int64_t>(appended, ev_capacity);
  dropped += appended - n;
  std::vector<RocksImpact> out(static_cast<size_t>(n));
  auto col = [&](const char* name) { return columns.at(name).second; };
  for (int64_t j = 0; j < n; j++) {
    const int32_t* I = &ev_ints[j * n_int];
    const double* R = &ev_reals[j * n_real];
    RocksImpact& e = out[j];
    e.time = R[col("time")] + t_ref;
    e.step = I[col("step")];
    e.vehicle = I[col("vehicle")];
    e.part = static_cast<int8_t>(I[col("part")]);
    e.damage = static_cast<int8_t>(I[col("damage")]);
    for (int c = 0; c < 3; c++) {
      e.point[c] = R[col("point") + c];
      e.normal[c] = R[col("normal") + c];
    }
    e.speed = R[col("speed")];
    e.normal_speed = R[col("normal_speed")];
    e.normal_momentum = R[col("normal_momentum")];
    e.energy = R[col("energy")];
    e.radius = R[col("radius")];
    e.rock = I[col("rock")];
    e.thrower = I[col("thrower")];
  }
  t_ref = t_now;
  std::stable_sort(out.begin(), out.end(), [](const RocksImpact& a, const RocksImpact& b) {
    if (a.step != b.step) return a.step < b.step;
    if (a.rock != b.rock) return a.rock < b.rock;
    return a.vehicle < b.vehicle;
  });
  kept += n;
  chunks.push_back(std::move(out));
  while (kept > keep && !chunks.empty()) {  // the host keeps at most KEEP events waiting
    kept -= static_cast<int64_t>(chunks.front().size());
    lost += static_cast<int64_t>(chunks.front().size());
    chunks.erase(chunks.begin());
  }
}

std::vector<RocksImpact> RocksSim::take_all() {
  drain(st.time);
  std::vector<RocksImpact> out;
  for (auto& c : chunks) out.insert(out.end(), c.begin(), c.end());
  chunks.clear();
  kept = 0;
  handed_out += static_cast<int64_t>(out.size());
  return out;
}

void RocksSim::changes(RocksChanges* out) {
  int width = spin ? 9 : 5;
  int64_t k = dev.gather_changes(rows, width);
  ids.resize(k);
  phase.resize(k);
  positions.resize(3 * k);
  orientations.resize(spin ? 4 * k : 0);
  for (int64_t j = 0; j < k; j++) {
    const double* r = &rows[j * width];
    ids[j] = static_cast<int32_t>(r[0]);
    phase[j] = static_cast<int8_t>(r[1]);
    for (int c = 0; c < 3; c++) positions[3 * j + c] = r[2 + c] + st.origin[c];
    if (spin)
      for (int c = 0; c < 4; c++) orientations[4 * j + c] = r[5 + c];
  }
  out->count = k;
  out->ids = ids.data();
  out->positions = positions.data();
  out->phase = phase.data();
  out->orientations = spin ? orientations.data() : nullptr;
}

namespace {

void keep_message(char* error, size_t size, const std::string& msg) {
  if (!error || !size) return;
  size_t n = std::min(size - 1, msg.size());
  std::memcpy(error, msg.data(), n);
  error[n] = '\0';
}

// runs `body` for `sim`, turning every exception into a status and the message rocks_last_error gives
template <class F>
int guarded(RocksSim* sim, bool steps, F body) {
  if (!sim) return ROCKS_ERROR_ARGUMENT;
  sim->error.clear();
  if (steps && sim->broken) {
    sim->error = "the simulation stopped after a device error; close it";
    return ROCKS_ERROR_STATE;
  }
  try {
    body();
    return ROCKS_OK;
  } catch (const Error& e) {
    sim->error = e.what();
    if (e.status == ROCKS_ERROR_DEVICE) sim->broken = true;
    return e.status;
  } catch (const std::bad_alloc&) {
    sim->error = "out of memory";
    return ROCKS_ERROR_MEMORY;
  } catch (const std::exception& e) {
    sim->error = e.what();
    sim->broken = true;
    return ROCKS_ERROR_DEVICE;
  } catch (...) {
    sim->error = "an unknown error";
    sim->broken = true;
    return ROCKS_ERROR_DEVICE;
  }
}

}  // namespace

extern "C" {

RocksSim* rocks_open(const char* module_dir, char* error, size_t error_size) {
  keep_message(error, error_size, "");
  if (!module_dir) {
    keep_message(error, error_size, "rocks_open: module_dir is NULL");
    return nullptr;
  }
  RocksSim* sim = nullptr;
  try {
    sim = new RocksSim();
    sim->load(module_dir);
    return sim;
  } catch (const std::bad_alloc&) {
    keep_message(error, error_size, "rocks_open: out of memory");
  } catch (const std::exception& e) {
    keep_message(error, error_size, e.what());
  } catch (...) {
    keep_message(error, error_size, "rocks_open: an unknown error");
  }
  delete sim;
  return nullptr;
}

const char* rocks_last_error(const RocksSim* sim) { return sim ? sim->error.c_str() : "rocks_last_error: sim is NULL"; }

int rocks_drive(RocksSim* sim, const char* vehicle, double x, double y, double heading, double speed,
                double yaw_rate, double wheel_spin) {
  return guarded(sim, false, [&] {
    if (!vehicle) throw Error(ROCKS_ERROR_ARGUMENT, "drive: vehicle is NULL");
    std::string name = vehicle;
    auto it = std::find(sim->names.begin(), sim->names.end(), name);
    if (it == sim->names.end()) throw Error(ROCKS_ERROR_ARGUMENT, "drive('" + name + "'): no vehicle of that name");
    rocks::Track& tr = sim->host->tracks()[it - sim->names.begin()];
    if (!tr.live())
      throw Error(ROCKS_ERROR_ARGUMENT, "drive('" + name + "'): a vehicle replaying its recorded drive; only a live "
                                        "vehicle (path kind \"live\" in the scene) is driven at run time");
    if (!std::isfinite(x) || !std::isfinite(y))
      throw Error(ROCKS_ERROR_ARGUMENT, "drive('" + name + "'): position must be finite");
    if (!std::isfinite(heading)) throw Error(ROCKS_ERROR_ARGUMENT, "drive('" + name + "'): heading must be finite");
    for (auto [what, v] : {std::pair{"speed", speed}, {"yaw_rate", yaw_rate}, {"wheel_spin", wheel_spin}})
      if (std::isinf(v)) throw Error(ROCKS_ERROR_ARGUMENT, "drive('" + name + "'): " + what + " must be finite");
    tr.set_pending({x, y, rocks::wrap_angle(heading), speed, yaw_rate, wheel_spin});
  });
}

int rocks_advance_to(RocksSim* sim, double t) {
  return guarded(sim, true, [&] {
    if (!std::isfinite(t)) throw Error(ROCKS_ERROR_ARGUMENT, "advance_to: t must be a finite time in seconds");
    if ((t - sim->st.time) / sim->dt > static_cast<double>(kStepLimit - sim->st.step_count - 1))
      throw Error(ROCKS_ERROR_ARGUMENT, "advance_to: t is past the last step the kernels count");
    double tol = 1e-9 * std::max(1.0, std::fabs(t));
    sim->host->bind(sim->st.time, t);
    while (sim->st.time + sim->dt <= t + tol) sim->step(sim->dt);
    if (t - sim->st.time > tol) sim->step(t - sim->st.time);
  });
}

int rocks_changes(RocksSim* sim, RocksChanges* out) {
  return guarded(sim, true, [&] {
    if (!out) throw Error(ROCKS_ERROR_ARGUMENT, "changes: out is NULL");
    *out = RocksChanges{0, nullptr, nullptr, nullptr, nullptr};
    if (!sim->drawn) return;
    sim->changes(out);
  });
}

int rocks_impacts(RocksSim* sim, RocksImpacts* out) {
  return guarded(sim, true, [&] {
    if (!out) throw Error(ROCKS_ERROR_ARGUMENT, "impacts: out is NULL");
    *out = RocksImpacts{0, nullptr};
    if (!sim->impacts) return;
    sim->impacts_out = sim->take_all();
    out->count = static_cast<int64_t>(sim->impacts_out.size());
    out->events = sim->impacts_out.data();
  });
}

int rocks_counts(RocksSim* sim, RocksCounts* out) {
  return guarded(sim, true, [&] {
    if (!out) throw Error(ROCKS_ERROR_ARGUMENT, "counts: out is NULL");
    RocksCounts c{};
    c.time = sim->st.time;
    c.steps = sim->st.step_count;
    c.rocks = sim->n_rocks;
    int32_t active = 0;
    sim->dev.read_i32(sim->fields["ipar"].element(sim->ipar_n_rocks), 1, &active);
    c.active = active;
    sim->dev.read_i64(sim->fields["launches"].element(0), 1, &c.launches);
    sim->dev.read_i64(sim->fields["recycles"].element(0), 1, &c.recycles);
    c.impacts = sim->handed_out;
    c.impacts_dropped = sim->dropped + sim->lost;
    *out = c;
  });
}

int rocks_vehicle_count(const RocksSim* sim) { return sim ? static_cast<int>(sim->names.size()) : 0; }

int rocks_vehicle(RocksSim* sim, int index, RocksVehicle* out) {
  return guarded(sim, false, [&] {
    if (!out) throw Error(ROCKS_ERROR_ARGUMENT, "vehicle: out is NULL");
    if (index < 0 || index >= static_cast<int>(sim->names.size()))
      throw Error(ROCKS_ERROR_ARGUMENT, "vehicle: index " + std::to_string(index) + " out of range");
    const rocks::VehiclePose& p = sim->st.poses[index];
    out->name = sim->names[index].c_str();
    out->live = sim->host->tracks()[index].live() ? 1 : 0;
    out->x = p.position[0];
    out->y = p.position[1];
    out->heading = p.heading;
    out->speed = p.speed;
  });
}

int rocks_buffer(RocksSim* sim, const char* name, RocksBuffer* out) {
  return guarded(sim, false, [&] {
    if (!out || !name) throw Error(ROCKS_ERROR_ARGUMENT, "buffer: NULL argument");
    const rocks::Json& fs = sim->manifest["fields"];
    for (size_t i = 0; i < fs.size(); i++) {
      if (fs[i]["name"].string() != name) continue;
      const rocks::Group& g = sim->dev.group(fs[i]["group"].string());
      int64_t row = fs[i]["row"].integer(), offset = fs[i]["offset"].integer();
      uint64_t entries = 1;
      for (size_t k = 0; k < fs[i]["shape"].size(); k++) entries *= fs[i]["shape"][k].integer();
      out->runtime = sim->dev.runtime();
      out->memory = reinterpret_cast<uint64_t>(g.memory);
      out->offset = static_cast<uint64_t>(row ? offset * row : offset) * g.element_bytes;
      out->count = entries;
      out->components = row ? static_cast<int32_t>(row) : g.components;
      out->type = static_cast<int32_t>(g.type);
      for (int c = 0; c < 3; c++) out->origin[c] = sim->st.origin[c];
      return;
    }
    throw Error(ROCKS_ERROR_ARGUMENT, std::string("buffer: no field ") + name + " (manifest.json: fields)");
  });
}

void rocks_close(RocksSim* sim) {
  try {
    delete sim;
  } catch (...) {
  }
}

}  // extern "C"
