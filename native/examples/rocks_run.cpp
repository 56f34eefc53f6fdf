// rocks_run: a console game loop over librocks (rocks.h). It opens a module, drives it for N frames at 60 Hz
// (the live vehicles steered here, weaving about their start heading; the others replay their recorded drives),
// reads what changed and the impacts each frame into the game's own mirror of the bed, and prints the per-call
// medians; its last line is one JSON object:
//   {"frames": N, "open_s": ..., "frame_ms": ..., "advance_ms": ..., "changes_ms": ..., "impacts_ms": ...}
// (medians over the frames after the first 30; open_s from the start of the program to the end of the first
// frame). With --dump OUT_DIR it writes the final state for comparison, in NumPy's .npy format: positions.npy
// (float64, a row of 3 per rock by id, world m), phase.npy (int8), orientations.npy (float64 x, y, z, w, with
// tumbling), impacts.npy (every event's time, vehicle, part, rock as float64 columns) and counts.json.
//
//   rocks_run MODULE_DIR [--frames N] [--fps F] [--dump OUT_DIR]
//
// Exit status: 0 done; 2 bad arguments or a module that cannot be opened; 1 a failure while running.
#include <rocks.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <sys/stat.h>
#include <vector>

namespace {

using Clock = std::chrono::steady_clock;
const Clock::time_point kStart = Clock::now();

double ms_since(Clock::time_point t) { return std::chrono::duration<double, std::milli>(Clock::now() - t).count(); }

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

// NumPy's .npy (version 1.0): the header dict padded to a multiple of 64 bytes with the magic string
bool write_npy(const std::string& path, const char* descr, const std::vector<size_t>& shape, const void* data,
               size_t bytes) {
  std::string dims;
  for (size_t i = 0; i < shape.size(); i++) dims += std::to_string(shape[i]) + (shape.size() == 1 || i + 1 < shape.size() ? "," : "");
  std::string header = std::string("{'descr': '") + descr + "', 'fortran_order': False, 'shape': (" + dims + "), }";
  header += std::string((64 - (10 + header.size() + 1) % 64) % 64, ' ') + "\n";
  std::string tmp = path + ".part";
  FILE* f = std::fopen(tmp.c_str(), "wb");
  if (!f) return false;
  unsigned char pre[10] = {0x93, 'N', 'U', 'M', 'P', 'Y', 1, 0, static_cast<unsigned char>(header.size() & 0xFF),
                           static_cast<unsigned char>(header.size() >> 8)};
  bool ok = std::fwrite(pre, 1, 10, f) == 10 && std::fwrite(header.data(), 1, header.size(), f) == header.size() &&
            (bytes == 0 || std::fwrite(data, 1, bytes, f) == bytes);
  ok = (std::fclose(f) == 0) && ok;
  return ok && std::rename(tmp.c_str(), path.c_str()) == 0;
}

int usage(const char* why) {
  std::fprintf(stderr, "rocks_run: %s\nusage: rocks_run MODULE_DIR [--frames N] [--fps F] [--dump OUT_DIR]\n", why);
  return 2;
}

struct Live {
  int index;
  std::string name;
  double x0, y0, h0, v;
};

}  // namespace

int main(int argc, char** argv) {
  std::string module, dump;
  long frames = 300;
  double fps = 60.0;
  for (int i = 1; i < argc; i++) {
    std::string a = argv[i];
    if ((a == "--frames" || a == "--fps" || a == "--dump") && i + 1 >= argc) return usage((a + " needs a value").c_str());
    if (a == "--frames") {
      char* end = nullptr;
      frames = std::strtol(argv[++i], &end, 10);
      if (*end || frames < 1) return usage("--frames: expected a whole number >= 1");
    } else if (a == "--fps") {
      char* end = nullptr;
      fps = std::strtod(argv[++i], &end);
      if (*end || !(fps > 0.0) || !std::isfinite(fps)) return usage("--fps: expected a number > 0");
    } else if (a == "--dump") {
      dump = argv[++i];
    } else if (!a.empty() && a[0] == '-') {
      return usage(("unknown option " + a).c_str());
    } else if (module.empty()) {
      module = a;
    } else {
      return usage("one module folder");
    }
  }
  if (module.empty()) return usage("no module folder");
  if (!dump.empty()) {
    struct stat s;
    if (stat(dump.c_str(), &s) != 0 || !S_ISDIR(s.st_mode)) return usage(("--dump: " + dump + ": not a folder").c_str());
  }

  char error[1024];
  RocksSim* sim = rocks_open(module.c_str(), error, sizeof error);
  if (!sim) {
    std::fprintf(stderr, "rocks_run: %s\n", error);
    return 2;
  }
  auto fail = [&](const char* what) {
    std::fprintf(stderr, "rocks_run: %s: %s\n", what, rocks_last_error(sim));
    rocks_close(sim);
    return 1;
  };
  RocksCounts counts;
  if (rocks_counts(sim, &counts) != ROCKS_OK) return fail("counts");
  const size_t n = static_cast<size_t>(counts.rocks);
  std::vector<double> positions(3 * n, 0.0), orientations;
  std::vector<int8_t> phase(n, 0);
  std::vector<double> impacts;  // time, vehicle, part, rock per event
  std::vector<Live> live;
  for (int i = 0; i < rocks_vehicle_count(sim); i++) {
    RocksVehicle v;
    if (rocks_vehicle(sim, i, &v) != ROCKS_OK) return fail("vehicle");
    if (v.live) live.push_back({i, v.name, v.x, v.y, v.heading, v.speed != 0.0 ? v.speed : 10.0});
  }

  std::vector<double> t_adv, t_chg, t_imp, t_frame;
  double open_s = 0.0;
  for (long f = 1; f <= frames; f++) {
    double t = f / fps;
    for (const Live& l : live) {  // the game's steering: along the start heading, weaving 4 m either side
      double s = l.v * t, side = 4.0 * std::sin(t);
      double c = std::cos(l.h0), sn = std::sin(l.h0);
      double heading = l.h0 + std::atan2(4.0 * std::cos(t), l.v);
      if (rocks_drive(sim, l.name.c_str(), l.x0 + s * c - side * sn, l.y0 + s * sn + side * c, heading, NAN, NAN,
                      NAN) != ROCKS_OK)
        return fail("drive");
    }
    auto t0 = Clock::now();
    if (rocks_advance_to(sim, t) != ROCKS_OK) return fail("advance_to");
    auto t1 = Clock::now();
    RocksChanges ch;
    if (rocks_changes(sim, &ch) != ROCKS_OK) return fail("changes");
    auto t2 = Clock::now();
    RocksImpacts im;
    if (rocks_impacts(sim, &im) != ROCKS_OK) return fail("impacts");
    auto t3 = Clock::now();
    // the game's side: its mirror of the bed, the hits it will draw
    if (ch.orientations && orientations.empty()) orientations.assign(4 * n, 0.0);
    for (int64_t k = 0; k < ch.count; k++) {
      size_t id = static_cast<size_t>(ch.ids[k]);
      std::memcpy(&positions[3 * id], &ch.positions[3 * k], 3 * sizeof(double));
      phase[id] = ch.phase[k];
      if (ch.orientations) std::memcpy(&orientations[4 * id], &ch.orientations[4 * k], 4 * sizeof(double));
    }
    for (int64_t k = 0; k < im.count; k++) {
      const RocksImpact& e = im.events[k];
      impacts.insert(impacts.end(), {e.time, static_cast<double>(e.vehicle), static_cast<double>(e.part),
                                     static_cast<double>(e.rock)});
    }
    using ms = std::chrono::duration<double, std::milli>;
    if (f == 1) open_s = ms_since(kStart) / 1e3;
    if (f > 30 || frames <= 30) {
      t_adv.push_back(ms(t1 - t0).count());
      t_chg.push_back(ms(t2 - t1).count());
      t_imp.push_back(ms(t3 - t2).count());
      t_frame.push_back(ms(t3 - t0).count());
    }
  }
  if (rocks_counts(sim, &counts) != ROCKS_OK) return fail("counts");
  std::printf("module %s: %zu rocks, %ld frames at %g Hz to t = %.4f s (%lld steps)\n", module.c_str(), n, frames,
              fps, counts.time, static_cast<long long>(counts.steps));
  std::printf("launches %lld, recycles %lld, impacts %lld, active %lld\n", static_cast<long long>(counts.launches),
              static_cast<long long>(counts.recycles), static_cast<long long>(counts.impacts),
              static_cast<long long>(counts.active));
  std::printf("medians: advance_to %.4f ms, changes %.4f ms, impacts %.4f ms, frame %.4f ms; open + first frame %.3f s\n",
              median(t_adv), median(t_chg), median(t_imp), median(t_frame), open_s);
  if (!dump.empty()) {
    bool ok = write_npy(dump + "/positions.npy", "<f8", {n, 3}, positions.data(), positions.size() * 8) &&
              write_npy(dump + "/phase.npy", "|i1", {n}, phase.data(), phase.size()) &&
              write_npy(dump + "/impacts.npy", "<f8", {impacts.size() / 4, 4}, impacts.data(), impacts.size() * 8) &&
              (orientations.empty() ||
               write_npy(dump + "/orientations.npy", "<f8", {n, 4}, orientations.data(), orientations.size() * 8));
    std::string counts_json = "{\"launches\": " + std::to_string(counts.launches) + ", \"recycles\": " +
                              std::to_string(counts.recycles) + ", \"impacts\": " + std::to_string(counts.impacts) +
                              ", \"steps\": " + std::to_string(counts.steps) + "}\n";
    FILE* f = ok ? std::fopen((dump + "/counts.json.part").c_str(), "wb") : nullptr;
    ok = f && std::fputs(counts_json.c_str(), f) >= 0;
    ok = f && (std::fclose(f) == 0) && ok;
    ok = ok && std::rename((dump + "/counts.json.part").c_str(), (dump + "/counts.json").c_str()) == 0;
    if (!ok) {
      std::fprintf(stderr, "rocks_run: --dump: cannot write into %s\n", dump.c_str());
      rocks_close(sim);
      return 1;
    }
  }
  rocks_close(sim);
  std::printf("{\"frames\": %ld, \"open_s\": %.6f, \"frame_ms\": %.6f, \"advance_ms\": %.6f, \"changes_ms\": %.6f, "
              "\"impacts_ms\": %.6f}\n",
              frames, open_s, median(t_frame), median(t_adv), median(t_chg), median(t_imp));
  return 0;
}
