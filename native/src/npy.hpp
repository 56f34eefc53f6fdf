// NumPy's .npy format (format versions 1-3, little-endian, C order): the module's buffers are read with it and
// rocks_run's --dump writes its arrays with it, so Python reads them with np.load.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace rocks {

struct NpyArray {
  std::string descr;           // NumPy's type string: "<f4", "<f8", "<i4", "<i8", "|i1"
  std::vector<uint64_t> shape;
  std::vector<char> data;      // the elements, C order
  uint64_t count() const;      // elements (the product of the shape)
};

// Reads `path`; throws Error(ROCKS_ERROR_MODULE) naming the file on anything that is not such a file.
NpyArray read_npy(const std::string& path);

// Writes `data` (C order) as an .npy file of `descr` and `shape`, through a temporary renamed into place; throws
// Error(ROCKS_ERROR_ARGUMENT) naming the file when it cannot be written.
void write_npy(const std::string& path, const std::string& descr, const std::vector<uint64_t>& shape,
               const void* data, size_t bytes);

// Writes `text` to `path` through a temporary renamed into place.
void write_text(const std::string& path, const std::string& text);

}  // namespace rocks
