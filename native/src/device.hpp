// The device side: Taichi's C API (taichi_core.h) with the module's kernels and the World's groups. Each call is
// checked; a failure throws Error(ROCKS_ERROR_DEVICE) with Taichi's message.
#pragma once

#include <taichi/taichi_core.h>

#include <initializer_list>
#include <map>
#include <string>
#include <vector>

#include "json.hpp"

namespace rocks {

// memory the host reads or writes (arguments of the copy kernels, the step's row, what changes() and the events
// come back in), as an ndarray of `type` and `shape`
struct HostArray {
  TiMemory memory = TI_NULL_HANDLE;
  uint64_t bytes = 0;
  TiNdArray nd{};
};

struct Group {
  std::string name;
  TiDataType type;
  int components;
  uint32_t length;
  size_t element_bytes;  // of one element (components x the scalar)
  TiMemory memory = TI_NULL_HANDLE;
  TiNdArray nd{};
};

class Device {
 public:
  // the runtime of `arch` ("x64" or "vulkan"), the module in `module_dir`, the groups of the manifest filled from
  // their files in `folder`; the kernels' arguments checked against what this library launches
  void open(const std::string& arch, const std::string& folder, const Json& manifest);
  ~Device();

  TiRuntime runtime() const { return rt_; }
  // with ROCKS_PROFILE=1 in the environment: each kernel waited for and timed; the means printed at close
  void report() const;
  const Group& group(const std::string& name) const;

  // the step's kernels (engine/stepdata.py load_batch, engine/active.py active_step and active_finish)
  void load_batch(const std::vector<double>& row);
  void active_step(int k, int step, int check_all);
  void active_finish(int k, int step);
  void move_origin();
  // engine/worlddata.py's copies: `count` elements of a group from element `first`
  void read_i32(uint32_t first, uint32_t count, int32_t* out);
  void read_i64(uint32_t first, uint32_t count, int64_t* out);
  void write_i32(uint32_t first, uint32_t count, const int32_t* in);
  void write_f64(uint32_t first, uint32_t count, const double* in);
  // changes(): the listed rows (engine/changes.py gather_counted) into `rows` (count x width float64)
  int64_t gather_changes(std::vector<double>& rows, int width);
  // the events since the last drain (engine/events.py take_counted): their count appended (kept or not), their
  // int columns and real columns (as float64)
  int64_t take_events(std::vector<int32_t>& ints, std::vector<double>& reals, int n_int, int n_real, int capacity);

 private:
  TiArch arch_ = TI_ARCH_X64;
  TiRuntime rt_ = TI_NULL_HANDLE;
  TiAotModule module_ = TI_NULL_HANDLE;
  std::vector<Group> groups_;
  std::map<std::string, TiKernel> kernels_;
  bool profile_ = false;
  std::map<std::string, std::vector<double>> times_;
  TiDataType real_ = TI_DATA_TYPE_F32;
  HostArray batch_, small_i32_, small_i64_, small_f64_, changes_, count_, ev_ints_, ev_reals_;

  void check(const char* what);
  HostArray array(TiDataType type, std::vector<uint32_t> shape, size_t scalar_bytes);
  void free_array(HostArray& a);
  void* map(TiMemory m, const char* what);
  void unmap(TiMemory m);
  void launch(const char* name, std::vector<TiArgument>& args);
  std::vector<TiArgument> with_groups() const;
  // launch kernel `name` over the World's groups, `outputs` and the count array, wait, and read the count it wrote
  int32_t launch_counted(const char* name, std::initializer_list<const HostArray*> outputs);
  void copy(const char* kernel, const std::string& group, uint32_t first, uint32_t count, HostArray& a);
  // copy `count` (at most 64) elements from `first` of a group into `out` through `a` and kernel `kernel`
  void read_small(const char* kernel, const char* group_name, uint32_t first, uint32_t count, HostArray& a,
                  void* out, size_t element_bytes);
  void check_kernel(const Json& manifest, const std::string& name, const std::vector<std::string>& want);
  void upload(Group& g, const std::string& path);
};

}  // namespace rocks
