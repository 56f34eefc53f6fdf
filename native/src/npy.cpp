// NumPy's .npy format (npy.hpp): the header is a Python dict literal, {'descr': '<f4', 'fortran_order': False,
// 'shape': (N, 3), }, padded with spaces and a newline so that the data starts at a multiple of 64 bytes.
#include "npy.hpp"

#include <cstdio>
#include <cstring>
#include <fstream>

#include "error.hpp"

namespace rocks {

uint64_t NpyArray::count() const {
  uint64_t n = 1;
  for (auto d : shape) n *= d;
  return n;
}

static size_t item_size(const std::string& descr) {
  if (descr.size() < 3) return 0;
  int n = std::atoi(descr.c_str() + 2);
  return n > 0 ? static_cast<size_t>(n) : 0;
}

// the text after 'key': in the header dict
static std::string entry(const std::string& header, const std::string& key) {
  size_t at = header.find("'" + key + "'");
  if (at == std::string::npos) return "";
  at = header.find(':', at);
  if (at == std::string::npos) return "";
  return header.substr(at + 1);
}

NpyArray read_npy(const std::string& path) {
  auto bad = [&](const std::string& why) { return Error(ROCKS_ERROR_MODULE, path + ": " + why); };
  std::ifstream f(path, std::ios::binary);
  if (!f) throw bad("cannot be read");
  char magic[8];
  if (!f.read(magic, 8) || std::memcmp(magic, "\x93NUMPY", 6) != 0) throw bad("not a NumPy .npy file");
  int major = static_cast<unsigned char>(magic[6]);
  uint32_t header_len = 0;
  if (major == 1) {
    unsigned char b[2];
    if (!f.read(reinterpret_cast<char*>(b), 2)) throw bad("a short header");
    header_len = b[0] | (b[1] << 8);
  } else if (major == 2 || major == 3) {
    unsigned char b[4];
    if (!f.read(reinterpret_cast<char*>(b), 4)) throw bad("a short header");
    header_len = b[0] | (b[1] << 8) | (b[2] << 16) | (static_cast<uint32_t>(b[3]) << 24);
  } else {
    throw bad("an .npy format version this library does not read (" + std::to_string(major) + ")");
  }
  if (header_len > (1u << 20)) throw bad("a header too long");
  std::string header(header_len, '\0');
  if (!f.read(header.data(), header_len)) throw bad("a short header");
  NpyArray a;
  std::string d = entry(header, "descr");
  size_t q0 = d.find('\''), q1 = q0 == std::string::npos ? q0 : d.find('\'', q0 + 1);
  if (q1 == std::string::npos) throw bad("no descr in the header");
  a.descr = d.substr(q0 + 1, q1 - q0 - 1);
  if (a.descr.size() < 3 || (a.descr[0] != '<' && a.descr[0] != '|') || item_size(a.descr) == 0)
    throw bad("an element type this library does not read (" + a.descr + ")");
  if (entry(header, "fortran_order").find("True") < entry(header, "fortran_order").find(','))
    throw bad("Fortran order (expected C order)");
  std::string s = entry(header, "shape");
  size_t p0 = s.find('('), p1 = s.find(')');
  if (p0 == std::string::npos || p1 == std::string::npos) throw bad("no shape in the header");
  std::string dims = s.substr(p0 + 1, p1 - p0 - 1);
  size_t i = 0;
  while (i < dims.size()) {
    while (i < dims.size() && (dims[i] == ' ' || dims[i] == ',')) i++;
    if (i >= dims.size()) break;
    size_t j = i;
    while (j < dims.size() && dims[j] >= '0' && dims[j] <= '9') j++;
    if (j == i) throw bad("a bad shape in the header");
    a.shape.push_back(std::stoull(dims.substr(i, j - i)));
    i = j;
  }
  uint64_t bytes = a.count() * item_size(a.descr);
  a.data.resize(bytes);
  if (bytes && !f.read(a.data.data(), static_cast<std::streamsize>(bytes))) throw bad("shorter than its shape");
  return a;
}

static void replace_file(const std::string& path, const std::string& head, const void* data, size_t bytes) {
  std::string tmp = path + ".part";
  {
    std::ofstream f(tmp, std::ios::binary | std::ios::trunc);
    if (!f) throw Error(ROCKS_ERROR_ARGUMENT, path + ": cannot be written");
    f.write(head.data(), static_cast<std::streamsize>(head.size()));
    if (bytes) f.write(static_cast<const char*>(data), static_cast<std::streamsize>(bytes));
    if (!f.flush()) {
      std::remove(tmp.c_str());
      throw Error(ROCKS_ERROR_ARGUMENT, path + ": cannot be written (disk full?)");
    }
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0) {
    std::remove(tmp.c_str());
    throw Error(ROCKS_ERROR_ARGUMENT, path + ": cannot be written");
  }
}

void write_npy(const std::string& path, const std::string& descr, const std::vector<uint64_t>& shape,
               const void* data, size_t bytes) {
  std::string dims;
  for (auto d : shape) dims += std::to_string(d) + ", ";
  if (shape.size() > 1) dims.resize(dims.size() - 2);  // (N, 3); a 1-d shape keeps its comma: (N,)
  else if (!shape.empty()) dims.resize(dims.size() - 1);
  std::string header = "{'descr': '" + descr + "', 'fortran_order': False, 'shape': (" + dims + "), }";
  size_t total = 10 + header.size() + 1;
  header += std::string((64 - total % 64) % 64, ' ') + "\n";
  std::string head = std::string("\x93NUMPY\x01\x00", 8);
  head += static_cast<char>(header.size() & 0xFF);
  head += static_cast<char>((header.size() >> 8) & 0xFF);
  head += header;
  replace_file(path, head, data, bytes);
}

void write_text(const std::string& path, const std::string& text) { replace_file(path, text, nullptr, 0); }

}  // namespace rocks
