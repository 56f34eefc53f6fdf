// Taichi's C API with the module's kernels and the World's groups (device.hpp).
#include "device.hpp"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>

#include "error.hpp"
#include "npy.hpp"

namespace rocks {

namespace {

const char* const kGroups[6] = {"r1", "r3", "r4", "i1", "d1", "l1"};

size_t scalar_bytes(TiDataType t) {
  return (t == TI_DATA_TYPE_F64 || t == TI_DATA_TYPE_I64) ? 8 : 4;
}

TiDataType data_type(const std::string& name, const std::string& where) {
  if (name == "f32") return TI_DATA_TYPE_F32;
  if (name == "f64") return TI_DATA_TYPE_F64;
  if (name == "i32") return TI_DATA_TYPE_I32;
  if (name == "i64") return TI_DATA_TYPE_I64;
  throw Error(ROCKS_ERROR_MODULE, where + ": an element type this library does not know (" + name + ")");
}

std::string descr_of(TiDataType t) {
  switch (t) {
    case TI_DATA_TYPE_F32: return "<f4";
    case TI_DATA_TYPE_F64: return "<f8";
    case TI_DATA_TYPE_I32: return "<i4";
    default: return "<i8";
  }
}

}  // namespace

void Device::check(const char* what) {
  uint64_t n = 0;
  TiError e = ti_get_last_error(&n, nullptr);
  if (e == TI_ERROR_SUCCESS) return;
  std::string msg(n, '\0');
  if (n) ti_get_last_error(&n, msg.data());
  while (!msg.empty() && (msg.back() == '\0' || msg.back() == '\n')) msg.pop_back();
  ti_set_last_error(TI_ERROR_SUCCESS, nullptr);
  throw Error(ROCKS_ERROR_DEVICE,
              std::string(what) + ": Taichi error " + std::to_string(e) + (msg.empty() ? "" : ": " + msg));
}

void* Device::map(TiMemory m, const char* what) {
  void* p = ti_map_memory(rt_, m);
  check(what);
  if (!p) throw Error(ROCKS_ERROR_DEVICE, std::string(what) + ": Taichi mapped no memory");
  return p;
}

void Device::unmap(TiMemory m) {
  ti_unmap_memory(rt_, m);
  check("unmap");
}

HostArray Device::array(TiDataType type, std::vector<uint32_t> shape, size_t bytes_each) {
  HostArray a;
  uint64_t n = 1;
  for (auto d : shape) n *= d;
  a.bytes = std::max<uint64_t>(n * bytes_each, 8);
  TiMemoryAllocateInfo info{};
  info.size = a.bytes;
  info.host_write = TI_TRUE;
  info.host_read = TI_TRUE;
  info.usage = TI_MEMORY_USAGE_STORAGE_BIT;
  a.memory = ti_allocate_memory(rt_, &info);
  check("allocate");
  if (a.memory == TI_NULL_HANDLE) throw Error(ROCKS_ERROR_DEVICE, "Taichi allocated no memory");
  a.nd.memory = a.memory;
  a.nd.shape.dim_count = static_cast<uint32_t>(shape.size());
  for (size_t i = 0; i < shape.size(); i++) a.nd.shape.dims[i] = shape[i];
  a.nd.elem_type = type;
  return a;
}

void Device::free_array(HostArray& a) {
  if (a.memory != TI_NULL_HANDLE) ti_free_memory(rt_, a.memory);
  a.memory = TI_NULL_HANDLE;
}

void Device::upload(Group& g, const std::string& path) {
  NpyArray a = read_npy(path);
  std::vector<uint64_t> want = {g.length};
  if (g.components > 1) want.push_back(static_cast<uint64_t>(g.components));
  if (a.descr != descr_of(g.type) || a.shape != want)
    throw Error(ROCKS_ERROR_MODULE, path + ": not the group the manifest names (" + descr_of(g.type) + ", " +
                                        std::to_string(g.length) + " elements of " +
                                        std::to_string(g.components) + ")");
  uint64_t bytes = static_cast<uint64_t>(g.length) * g.element_bytes;
  TiMemoryAllocateInfo info{};
  info.size = bytes;
  info.usage = TI_MEMORY_USAGE_STORAGE_BIT;
  bool direct = arch_ == TI_ARCH_X64;  // the CPU's memory is the host's: written in place
  info.host_write = direct ? TI_TRUE : TI_FALSE;
  info.host_read = direct ? TI_TRUE : TI_FALSE;
  g.memory = ti_allocate_memory(rt_, &info);
  check("allocate a group");
  if (g.memory == TI_NULL_HANDLE) throw Error(ROCKS_ERROR_DEVICE, "Taichi allocated no memory for " + g.name);
  if (direct) {
    std::memcpy(map(g.memory, "map a group"), a.data.data(), bytes);
    unmap(g.memory);
  } else {  // a device's own memory: through a staging buffer the host writes
    TiMemoryAllocateInfo s{};
    s.size = bytes;
    s.host_write = TI_TRUE;
    s.usage = TI_MEMORY_USAGE_STORAGE_BIT;
    TiMemory staging = ti_allocate_memory(rt_, &s);
    check("allocate a staging buffer");
    std::memcpy(map(staging, "map a staging buffer"), a.data.data(), bytes);
    unmap(staging);
    TiMemorySlice dst{g.memory, 0, bytes}, src{staging, 0, bytes};
    ti_copy_memory_device_to_device(rt_, &dst, &src);
    check("copy a group to the device");
    ti_wait(rt_);
    check("wait");
    ti_free_memory(rt_, staging);
  }
  g.nd = TiNdArray{};
  g.nd.memory = g.memory;
  g.nd.shape.dim_count = 1;
  g.nd.shape.dims[0] = g.length;
  if (g.components > 1) {
    g.nd.elem_shape.dim_count = 1;
    g.nd.elem_shape.dims[0] = static_cast<uint32_t>(g.components);
  }
  g.nd.elem_type = g.type;
}

void Device::check_kernel(const Json& manifest, const std::string& name, const std::vector<std::string>& want) {
  const Json& args = manifest["kernels"][name]["args"];
  std::vector<std::string> got;
  for (size_t i = 0; i < args.size(); i++) {
    const Json& a = args[i];
    const std::string& kind = a["kind"].string();
    if (kind == "group") got.push_back("group " + a["group"].string());
    else if (kind == "i32") got.push_back("i32 " + a["name"].string());
    else got.push_back("array " + a["dtype"].string() + " " + std::to_string(a["ndim"].integer()) + " " +
                       a["name"].string());
  }
  if (got != want) {
    auto join = [](const std::vector<std::string>& v) {
      std::string s;
      for (auto& x : v) s += (s.empty() ? "" : ", ") + x;
      return s;
    };
    throw Error(ROCKS_ERROR_MODULE, "manifest.json: kernel " + name + " takes (" + join(got) +
                                        "), this library launches it with (" + join(want) +
                                        "): a module of another version");
  }
}

void Device::open(const std::string& arch, const std::string& folder, const Json& manifest) {
  const char* prof = std::getenv("ROCKS_PROFILE");
  profile_ = prof && std::string(prof) == "1";
  if (arch == "x64") arch_ = TI_ARCH_X64;
  else if (arch == "vulkan") arch_ = TI_ARCH_VULKAN;
  else throw Error(ROCKS_ERROR_MODULE, "manifest.json: arch: \"" + arch + "\" is not x64 or vulkan");
  // (not ti_get_available_archs: Taichi 1.7.4's probes a CUDA driver that may be absent and crashes there)
  rt_ = ti_create_runtime(arch_, 0);
  try {
    check("create the runtime");
  } catch (const Error& e) {
    rt_ = TI_NULL_HANDLE;
    throw Error(ROCKS_ERROR_DEVICE, "the module is for " + arch + ", whose runtime Taichi cannot create here (" +
                                        e.what() + ")");
  }
  if (rt_ == TI_NULL_HANDLE)
    throw Error(ROCKS_ERROR_DEVICE, "the module is for " + arch + ", whose runtime Taichi cannot create here");
  module_ = ti_load_aot_module(rt_, (folder + "/module").c_str());
  uint64_t msg_n = 0;
  if (ti_get_last_error(&msg_n, nullptr) != TI_ERROR_SUCCESS || module_ == TI_NULL_HANDLE) {
    try {
      check("load the module");
    } catch (const Error& e) {
      throw Error(ROCKS_ERROR_MODULE, folder + "/module: cannot be loaded (" + std::string(e.what()) + ")");
    }
    throw Error(ROCKS_ERROR_MODULE, folder + "/module: cannot be loaded");
  }
  real_ = manifest["precision"].string() == "f64" ? TI_DATA_TYPE_F64 : TI_DATA_TYPE_F32;
  std::string real = manifest["precision"].string();
  std::vector<std::string> g6;
  for (const char* g : kGroups) g6.push_back(std::string("group ") + g);
  auto with = [&](std::vector<std::string> extra) {
    std::vector<std::string> v = g6;
    v.insert(v.end(), extra.begin(), extra.end());
    return v;
  };
  const bool drawn = manifest["host"]["drawn"].boolean(), impacts = manifest["host"]["impacts"].boolean();
  std::map<std::string, std::vector<std::string>> want = {
      {"load_batch", with({"array f64 2 data"})},
      {"active_step", with({"i32 k", "i32 step", "i32 check_all"})},
      {"active_finish", with({"i32 k", "i32 step"})},
      {"move_origin", g6},
      {"read_i32", {"group i1", "i32 off", "i32 k", "array i32 1 out"}},
      {"write_i32", {"group i1", "i32 off", "i32 k", "array i32 1 a"}},
      {"read_i64", {"group l1", "i32 off", "i32 k", "array i64 1 out"}},
      {"write_f64", {"group d1", "i32 off", "i32 k", "array f64 1 a"}}};
  if (drawn) want["gather_counted"] = with({"array f64 2 out", "array i32 1 count"});
  if (impacts) want["take_counted"] = with({"array i32 2 ints", "array " + real + " 2 reals", "array i32 1 count"});
  for (auto& [name, args] : want) {
    if (!manifest["kernels"].has(name))
      throw Error(ROCKS_ERROR_MODULE, "manifest.json: kernels: no kernel " + name);
    check_kernel(manifest, name, args);
    TiKernel k = ti_get_aot_module_kernel(module_, name.c_str());
    uint64_t m = 0;
    if (ti_get_last_error(&m, nullptr) != TI_ERROR_SUCCESS || k == TI_NULL_HANDLE) {
      ti_set_last_error(TI_ERROR_SUCCESS, nullptr);
      throw Error(ROCKS_ERROR_MODULE, folder + "/module: no kernel " + name);
    }
    kernels_[name] = k;
  }
  const Json& gs = manifest["groups"];
  if (gs.size() != 6) throw Error(ROCKS_ERROR_MODULE, "manifest.json: groups: expected the 6 groups of the World");
  for (size_t i = 0; i < 6; i++) {
    const Json& gj = gs[i];
    Group g;
    g.name = gj["name"].string();
    if (g.name != kGroups[i])
      throw Error(ROCKS_ERROR_MODULE, gj.path() + ": expected group " + kGroups[i] + ", got " + g.name);
    g.type = data_type(gj["dtype"].string(), gj.path());
    g.components = static_cast<int>(gj["components"].integer());
    int64_t len = gj["length"].integer();
    if (g.components < 1 || g.components > 4 || len < 1 || len > 0x7FFFFFFF)
      throw Error(ROCKS_ERROR_MODULE, gj.path() + ": a group's shape out of range");
    g.length = static_cast<uint32_t>(len);
    g.element_bytes = scalar_bytes(g.type) * static_cast<size_t>(g.components);
    groups_.push_back(g);
    upload(groups_.back(), folder + "/" + gj["file"].string());
  }
  // every array the host reads or writes, now: Taichi 1.7.4's CPU runtime allocates no memory once a kernel ran
  small_i32_ = array(TI_DATA_TYPE_I32, {64}, 4);
  small_i64_ = array(TI_DATA_TYPE_I64, {64}, 8);
  small_f64_ = array(TI_DATA_TYPE_F64, {64}, 8);
  count_ = array(TI_DATA_TYPE_I32, {1}, 4);
  const Json& h = manifest["host"];
  int64_t width = 2 * h["frame_rows"].integer() + h["n_tires"].integer() * h["ray_fields"].integer() +
                  2 * h["step_bodies"].integer();
  batch_ = array(TI_DATA_TYPE_F64, {1, static_cast<uint32_t>(width)}, 8);
  if (drawn) {  // room for every rock: each is listed at most once between two reads
    uint32_t rocks = static_cast<uint32_t>(std::max<int64_t>(1, manifest["rocks"].integer()));
    changes_ = array(TI_DATA_TYPE_F64, {rocks, h["spin"].boolean() ? 9u : 5u}, 8);
  }
  if (impacts) {
    const Json& e = h["events"];
    uint32_t cap = static_cast<uint32_t>(e["capacity"].integer());
    ev_ints_ = array(TI_DATA_TYPE_I32, {cap, static_cast<uint32_t>(e["ints"].integer())}, 4);
    ev_reals_ = array(real_, {cap, static_cast<uint32_t>(e["reals"].integer())}, scalar_bytes(real_));
  }
}

Device::~Device() {
  if (rt_ == TI_NULL_HANDLE) return;
  if (profile_) report();
  if (arch_ != TI_ARCH_X64) {  // (the CPU runtime frees no memory by itself: its destruction frees it all)
    for (HostArray* a : {&batch_, &small_i32_, &small_i64_, &small_f64_, &changes_, &count_, &ev_ints_, &ev_reals_})
      free_array(*a);
    for (Group& g : groups_)
      if (g.memory != TI_NULL_HANDLE) ti_free_memory(rt_, g.memory);
  }
  if (module_ != TI_NULL_HANDLE) ti_destroy_aot_module(module_);
  ti_destroy_runtime(rt_);
  ti_set_last_error(TI_ERROR_SUCCESS, nullptr);
}

const Group& Device::group(const std::string& name) const {
  for (const Group& g : groups_)
    if (g.name == name) return g;
  throw Error(ROCKS_ERROR_MODULE, "no group " + name);
}

std::vector<TiArgument> Device::with_groups() const {
  std::vector<TiArgument> args;
  args.reserve(10);
  for (const Group& g : groups_) {
    TiArgument a{};
    a.type = TI_ARGUMENT_TYPE_NDARRAY;
    a.value.ndarray = g.nd;
    args.push_back(a);
  }
  return args;
}

static TiArgument i32_arg(int32_t v) {
  TiArgument a{};
  a.type = TI_ARGUMENT_TYPE_I32;
  a.value.i32 = v;
  return a;
}

static TiArgument nd_arg(const TiNdArray& nd) {
  TiArgument a{};
  a.type = TI_ARGUMENT_TYPE_NDARRAY;
  a.value.ndarray = nd;
  return a;
}

void Device::launch(const char* name, std::vector<TiArgument>& args) {
  auto t0 = std::chrono::steady_clock::now();
  ti_launch_kernel(rt_, kernels_.at(name), static_cast<uint32_t>(args.size()), args.data());
  check(name);
  if (profile_) {
    ti_wait(rt_);
    check("wait");
    times_[name].push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
  }
}

void Device::report() const {
  for (auto [name, t] : times_) {
    std::sort(t.begin(), t.end());
    double sum = 0;
    for (double x : t) sum += x;
    std::fprintf(stderr, "rocks: %-16s %7zu launches, median %.4f ms, max %.4f ms, total %.1f ms\n", name.c_str(),
                 t.size(), t[t.size() / 2], t.back(), sum);
  }
}

void Device::load_batch(const std::vector<double>& row) {
  if (row.size() != batch_.nd.shape.dims[1])
    throw Error(ROCKS_ERROR_ARGUMENT, "load_batch: a row of " + std::to_string(row.size()) + " values for " +
                                          std::to_string(batch_.nd.shape.dims[1]));
  ti_wait(rt_);  // the previous step's load_batch may still read it
  check("wait");
  std::memcpy(map(batch_.memory, "map the step's row"), row.data(), row.size() * sizeof(double));
  unmap(batch_.memory);
  auto args = with_groups();
  args.push_back(nd_arg(batch_.nd));
  launch("load_batch", args);
}

void Device::active_step(int k, int step, int check_all) {
  auto args = with_groups();
  args.push_back(i32_arg(k));
  args.push_back(i32_arg(step));
  args.push_back(i32_arg(check_all));
  launch("active_step", args);
}

void Device::active_finish(int k, int step) {
  auto args = with_groups();
  args.push_back(i32_arg(k));
  args.push_back(i32_arg(step));
  launch("active_finish", args);
}

void Device::move_origin() {
  auto args = with_groups();
  launch("move_origin", args);
}

void Device::copy(const char* kernel, const std::string& group_name, uint32_t first, uint32_t count, HostArray& a) {
  std::vector<TiArgument> args;
  args.push_back(nd_arg(group(group_name).nd));
  args.push_back(i32_arg(static_cast<int32_t>(first)));
  args.push_back(i32_arg(static_cast<int32_t>(count)));
  args.push_back(nd_arg(a.nd));
  launch(kernel, args);
}

void Device::read_small(const char* kernel, const char* group_name, uint32_t first, uint32_t count, HostArray& a,
                        void* out, size_t element_bytes) {
  if (count > 64) throw Error(ROCKS_ERROR_ARGUMENT, std::string(kernel) + ": at most 64 elements at a time");
  copy(kernel, group_name, first, count, a);
  ti_wait(rt_);
  check("wait");
  std::memcpy(out, map(a.memory, "map"), count * element_bytes);
  unmap(a.memory);
}

void Device::read_i32(uint32_t first, uint32_t count, int32_t* out) {
  read_small("read_i32", "i1", first, count, small_i32_, out, 4);
}

void Device::read_i64(uint32_t first, uint32_t count, int64_t* out) {
  read_small("read_i64", "l1", first, count, small_i64_, out, 8);
}

void Device::write_i32(uint32_t first, uint32_t count, const int32_t* in) {
  if (count > 64) throw Error(ROCKS_ERROR_ARGUMENT, "write_i32: at most 64 elements at a time");
  ti_wait(rt_);  // the array may still be read by a launch in flight
  check("wait");
  std::memcpy(map(small_i32_.memory, "map"), in, count * 4);
  unmap(small_i32_.memory);
  copy("write_i32", "i1", first, count, small_i32_);
}

void Device::write_f64(uint32_t first, uint32_t count, const double* in) {
  if (count > 64) throw Error(ROCKS_ERROR_ARGUMENT, "write_f64: at most 64 elements at a time");
  ti_wait(rt_);
  check("wait");
  std::memcpy(map(small_f64_.memory, "map"), in, count * 8);
  unmap(small_f64_.memory);
  copy("write_f64", "d1", first, count, small_f64_);
}

int32_t Device::launch_counted(const char* name, std::initializer_list<const HostArray*> outputs) {
  auto args = with_groups();
  for (const HostArray* b : outputs) args.push_back(nd_arg(b->nd));
  args.push_back(nd_arg(count_.nd));
  launch(name, args);
  ti_wait(rt_);
  check("wait");
  int32_t count = 0;
  std::memcpy(&count, map(count_.memory, "map"), 4);
  unmap(count_.memory);
  return count;
}

int64_t Device::gather_changes(std::vector<double>& rows, int width) {
  if (changes_.memory == TI_NULL_HANDLE || changes_.nd.shape.dims[1] != static_cast<uint32_t>(width))
    throw Error(ROCKS_ERROR_ARGUMENT, "changes: the module keeps no mirror of that width");
  const int32_t k = launch_counted("gather_counted", {&changes_});
  if (k < 0 || static_cast<uint32_t>(k) > changes_.nd.shape.dims[0])
    throw Error(ROCKS_ERROR_DEVICE, "changes: " + std::to_string(k) + " rows listed, more than the rocks");
  rows.resize(static_cast<size_t>(k) * width);
  if (k) {
    std::memcpy(rows.data(), map(changes_.memory, "map"), rows.size() * sizeof(double));
    unmap(changes_.memory);
  }
  return k;
}

int64_t Device::take_events(std::vector<int32_t>& ints, std::vector<double>& reals, int n_int, int n_real,
                            int capacity) {
  if (ev_ints_.memory == TI_NULL_HANDLE || ev_ints_.nd.shape.dims[0] != static_cast<uint32_t>(capacity))
    throw Error(ROCKS_ERROR_ARGUMENT, "impacts: the module keeps no event buffer of that capacity");
  const int32_t appended = launch_counted("take_counted", {&ev_ints_, &ev_reals_});
  int64_t n = std::min<int64_t>(appended, capacity);
  ints.resize(static_cast<size_t>(n) * n_int);
  reals.resize(static_cast<size_t>(n) * n_real);
  if (n) {
    std::memcpy(ints.data(), map(ev_ints_.memory, "map"), ints.size() * 4);
    unmap(ev_ints_.memory);
    const char* p = static_cast<const char*>(map(ev_reals_.memory, "map"));
    for (size_t j = 0; j < reals.size(); j++) {
      if (real_ == TI_DATA_TYPE_F64) {
        std::memcpy(&reals[j], p + 8 * j, 8);
      } else {
        float f;
        std::memcpy(&f, p + 4 * j, 4);
        reals[j] = f;
      }
    }
    unmap(ev_reals_.memory);
  }
  return appended;
}

}  // namespace rocks
