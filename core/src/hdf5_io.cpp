#include "hdf5_io.h"

#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>

#include "mvtwin/core/error.h"

namespace mvtwin::h5 {
namespace {

// HDF5 prints its own error stack to stderr by default; mvtwin reports errors itself.
void silence_hdf5() {
  static const bool done = [] {
    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
    return true;
  }();
  (void)done;
}

std::string dims_string(const std::vector<hsize_t>& d) {
  std::string s = "(";
  for (size_t i = 0; i < d.size(); ++i) s += (i ? ", " : "") + std::to_string(d[i]);
  return s + ")";
}

// Bounded reads of a file's bytes (for decoding what libhdf5 would decode unchecked).
class FileBytes {
 public:
  FileBytes(const std::string& path, std::uint64_t size)
      : in_(path, std::ios::binary), size_(size) {}
  bool read(std::uint64_t at, std::uint64_t n, std::vector<unsigned char>* out) {
    if (!in_ || at > size_ || n > size_ - at) return false;
    out->resize(static_cast<size_t>(n));
    in_.seekg(static_cast<std::streamoff>(at));
    in_.read(reinterpret_cast<char*>(out->data()), static_cast<std::streamsize>(n));
    return static_cast<std::uint64_t>(in_.gcount()) == n;
  }

 private:
  std::ifstream in_;
  std::uint64_t size_;
};

std::uint64_t little_endian(const unsigned char* p, size_t n) {
  std::uint64_t v = 0;
  for (size_t i = n; i-- > 0;) v = (v << 8) | p[i];
  return v;
}

// Variable-length strings are where libhdf5 1.10 trusts a corrupt file most: H5T__conv_vlen
// allocates what a string's descriptor claims (1.95 GB for
// tests/fuzz/regressions/fuzz_simulation/vlen-string-2gb.h5) and H5HG_read copies a heap object at
// the size the heap claims (an overlapping memcpy: .../fuzz_calibration/heap-object-overlap.h5),
// both before any check. So a contiguous, unfiltered dataset of them (how mvtwin writes them) is
// decoded here from the file's bytes, each length checked against the heap object that holds
// it (HDF5 file format spec, "Global Heap" and "Variable-length data"); other layouts go through
// libhdf5. Returns false when the dataset is not stored that way.
bool read_vlen_strings_directly(const Location& loc, const std::string& name, hid_t ds,
                                std::uint64_t n, std::uint64_t file_bytes,
                                std::vector<std::string>* out) {
  const Handle dcpl(H5Dget_create_plist(ds), H5Pclose);
  if (!dcpl.valid() || H5Pget_layout(dcpl.get()) != H5D_CONTIGUOUS ||
      H5Pget_nfilters(dcpl.get()) != 0)
    return false;
  const Handle file(H5Iget_file_id(ds), H5Fclose);
  const Handle fcpl(H5Fget_create_plist(file.get()), H5Pclose);
  size_t sizeof_addr = 0, sizeof_size = 0;
  hsize_t userblock = 0;
  if (!fcpl.valid() || H5Pget_sizes(fcpl.get(), &sizeof_addr, &sizeof_size) < 0 ||
      H5Pget_userblock(fcpl.get(), &userblock) < 0 || userblock != 0 || sizeof_addr > 8 ||
      sizeof_size > 8 || sizeof_addr < 2 || sizeof_size < 2)
    return false;
  const haddr_t at = H5Dget_offset(ds);
  out->assign(static_cast<size_t>(n), std::string());
  if (at == HADDR_UNDEF) return true;  // never written: the fill value, empty strings
  auto corrupt = [&](const std::string& what) { loc.fail(name, what + " (file corrupt?)"); };
  FileBytes bytes(loc.file(), file_bytes);
  const size_t desc = 4 + sizeof_addr + 4;  // length, heap collection address, object index
  std::vector<unsigned char> descriptors, collection;
  if (!bytes.read(at, n * desc, &descriptors)) corrupt("the strings' descriptors lie past the end");
  std::uint64_t collection_at = HADDR_UNDEF;
  const size_t header = 8 + sizeof_size, object_header = 8 + sizeof_size;
  for (std::uint64_t i = 0; i < n; ++i) {
    const unsigned char* d = descriptors.data() + i * desc;
    const std::uint64_t length = little_endian(d, 4);
    const std::uint64_t heap = little_endian(d + 4, sizeof_addr);
    const std::uint64_t index = little_endian(d + 4 + sizeof_addr, 4);
    if (length == 0) continue;
    if (heap != collection_at) {
      std::vector<unsigned char> head;
      if (!bytes.read(heap, header, &head) ||
          std::string(head.begin(), head.begin() + 4) != "GCOL" || head[4] != 1)
        corrupt("string " + std::to_string(i) + " points to no global heap");
      const std::uint64_t size = little_endian(head.data() + 8, sizeof_size);
      if (size < header || !bytes.read(heap, size, &collection))
        corrupt("a global heap claims more bytes than the file holds");
      collection_at = heap;
    }
    bool found = false;
    for (std::uint64_t pos = header; pos + object_header <= collection.size();) {
      const unsigned char* o = collection.data() + pos;
      const std::uint64_t id = little_endian(o, 2);
      const std::uint64_t size = little_endian(o + 8, sizeof_size);
      if (id == 0) break;  // free space ends the objects
      const std::uint64_t data = pos + object_header;
      if (size > collection.size() - data) corrupt("a global heap object runs past its heap");
      if (id == index) {
        if (length > size)
          corrupt("string " + std::to_string(i) + " claims " + std::to_string(length) +
                  " bytes, its heap object holds " + std::to_string(size));
        const char* c = reinterpret_cast<const char*>(collection.data() + data);
        (*out)[static_cast<size_t>(i)].assign(c, strnlen(c, static_cast<size_t>(length)));
        found = true;
        break;
      }
      pos = data + ((size + 7) / 8) * 8;
    }
    if (!found) corrupt("string " + std::to_string(i) + "'s heap object is missing");
  }
  return true;
}

// Links (groups) and attributes stay in the object header, under its checksum, however many
// there are (libhdf5 moves them to a fractal heap past 8 by default).
bool keep_compact(hid_t create_plist, bool group) {
  if (H5Pset_attr_phase_change(create_plist, 65535, 0) < 0) return false;
  return !group || H5Pset_link_phase_change(create_plist, 65535, 65534) >= 0;
}

Handle string_type() {
  Handle t(H5Tcopy(H5T_C_S1), H5Tclose);
  H5Tset_size(t.get(), H5T_VARIABLE);
  H5Tset_cset(t.get(), H5T_CSET_UTF8);
  return t;
}

}  // namespace

Handle& Handle::operator=(Handle&& o) noexcept {
  if (this != &o) {
    reset();
    id_ = o.id_;
    close_ = o.close_;
    o.id_ = H5I_INVALID_HID;
  }
  return *this;
}

void Handle::reset() {
  if (id_ >= 0 && close_) close_(id_);
  id_ = H5I_INVALID_HID;
}

void Location::fail(const std::string& name, const std::string& problem) const {
  throw Error(file_ + ": " + (name.empty() ? path_ : full(name)) + ": " + problem);
}

Location Location::create_file(const std::filesystem::path& path) {
  silence_hdf5();
  // The HDF5 1.10 file format (superblock version 3, version-2 object headers, chunk indexes of
  // version 4 layouts): every metadata block carries a checksum that libhdf5 verifies before
  // decoding it, so a file damaged on disk or in transfer is refused ("incorrect metadata
  // checksum") instead of decoded, where libhdf5 1.10 has known crashes on malformed metadata
  // (docs/fuzzing.md). Links and attributes are kept in the object headers (compact storage):
  // the fractal heaps of dense storage leave their data blocks unchecksummed. Read by HDF5 1.10
  // and later (h5py, ParaView, 3D Slicer).
  Handle fapl(H5Pcreate(H5P_FILE_ACCESS), H5Pclose);
  if (!fapl.valid() || H5Pset_libver_bounds(fapl.get(), H5F_LIBVER_V110, H5F_LIBVER_V110) < 0)
    throw Error(path.string() + ": cannot set up the HDF5 file format");
  Handle fcpl(H5Pcreate(H5P_FILE_CREATE), H5Pclose);
  if (!fcpl.valid() || !keep_compact(fcpl.get(), true))
    throw Error(path.string() + ": cannot set up the HDF5 file format");
  const hid_t id = H5Fcreate(path.c_str(), H5F_ACC_TRUNC, fcpl.get(), fapl.get());
  if (id < 0)
    throw Error(path.string() + ": cannot create HDF5 file (directory missing or not writable?)");
  return Location(Handle(id, H5Fclose), path.string(), "/");
}

Location Location::open_file(const std::filesystem::path& path) {
  silence_hdf5();
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) throw Error(path.string() + ": no such file");
  if (std::filesystem::is_directory(path, ec))
    throw Error(path.string() + ": is a directory, not a file");
  {
    std::ifstream f(path, std::ios::binary);
    if (!f) throw Error(path.string() + ": cannot be opened for reading (permissions?)");
  }
  if (H5Fis_hdf5(path.c_str()) <= 0) {
    throw Error(path.string() + ": not an HDF5 file (wrong file, or truncated/corrupt)");
  }
  const hid_t id = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
  if (id < 0) throw Error(path.string() + ": HDF5 file cannot be opened (truncated or corrupt?)");
  return Location(Handle(id, H5Fclose), path.string(), "/");
}

Location Location::create_group(const std::string& name, bool track_order) const {
  Handle plist(H5Pcreate(H5P_GROUP_CREATE), H5Pclose);
  if (!keep_compact(plist.get(), true)) fail(name, "cannot set up the group");
  if (track_order) {
    H5Pset_link_creation_order(plist.get(), H5P_CRT_ORDER_TRACKED | H5P_CRT_ORDER_INDEXED);
  }
  const hid_t g = H5Gcreate2(id(), name.c_str(), H5P_DEFAULT, plist.get(), H5P_DEFAULT);
  if (g < 0) fail(name, "cannot create group");
  return Location(Handle(g, H5Gclose), file_, full(name));
}

Location Location::open_group(const std::string& name) const {
  if (!exists(name)) fail(name, "group is missing");
  const hid_t g = H5Gopen2(id(), name.c_str(), H5P_DEFAULT);
  if (g < 0) fail(name, "cannot open group (is it a dataset?)");
  return Location(Handle(g, H5Gclose), file_, full(name));
}

bool Location::exists(const std::string& name) const {
  return H5Lexists(id(), name.c_str(), H5P_DEFAULT) > 0;
}

namespace {

template <typename T>
void write_dataset(const Location& loc, const std::string& name, hid_t type, const T* data,
                   const std::vector<hsize_t>& dims, bool compress) {
  Handle space(H5Screate_simple(static_cast<int>(dims.size()), dims.data(), nullptr), H5Sclose);
  Handle plist(H5Pcreate(H5P_DATASET_CREATE), H5Pclose);
  if (!keep_compact(plist.get(), false)) loc.fail(name, "cannot set up the dataset");
  hsize_t total = 1;
  for (hsize_t d : dims) total *= d;
  if (compress && total > 0) {
    std::vector<hsize_t> chunk(dims);
    // Chunks of at most ~1M elements along the slowest axis.
    hsize_t inner = 1;
    for (size_t i = 1; i < dims.size(); ++i) inner *= dims[i];
    chunk[0] =
        std::max<hsize_t>(1, std::min<hsize_t>(dims[0], (1u << 20) / std::max<hsize_t>(inner, 1)));
    H5Pset_chunk(plist.get(), static_cast<int>(chunk.size()), chunk.data());
    H5Pset_deflate(plist.get(), 4);
  }
  Handle ds(
      H5Dcreate2(loc.id(), name.c_str(), type, space.get(), H5P_DEFAULT, plist.get(), H5P_DEFAULT),
      H5Dclose);
  if (!ds.valid()) loc.fail(name, "cannot create dataset");
  if (total > 0 && H5Dwrite(ds.get(), type, H5S_ALL, H5S_ALL, H5P_DEFAULT, data) < 0) {
    loc.fail(name, "cannot write dataset (disk full?)");
  }
}

}  // namespace

void Location::write(const std::string& name, const std::vector<double>& data,
                     const std::vector<hsize_t>& dims, const char* units) const {
  write_dataset(*this, name, H5T_NATIVE_DOUBLE, data.data(), dims, false);
  if (units) attr("units", std::string(units), name);
}

void Location::write(const std::string& name, const std::vector<float>& data,
                     const std::vector<hsize_t>& dims, bool compress) const {
  write_dataset(*this, name, H5T_NATIVE_FLOAT, data.data(), dims, compress);
}

void Location::write(const std::string& name, const std::vector<std::uint8_t>& data,
                     const std::vector<hsize_t>& dims) const {
  write_dataset(*this, name, H5T_NATIVE_UINT8, data.data(), dims, false);
}

void Location::write(const std::string& name, const std::vector<int>& data,
                     const std::vector<hsize_t>& dims) const {
  write_dataset(*this, name, H5T_NATIVE_INT, data.data(), dims, false);
}

void Location::write_strings(const std::string& name, const std::vector<std::string>& s) const {
  std::vector<const char*> ptrs;
  for (const auto& x : s) ptrs.push_back(x.c_str());
  const Handle t = string_type();
  write_dataset(*this, name, t.get(), ptrs.data(), {static_cast<hsize_t>(s.size())}, false);
}

void Location::write_scalar(const std::string& name, double v, const char* units) const {
  Handle space(H5Screate(H5S_SCALAR), H5Sclose);
  Handle ds(H5Dcreate2(id(), name.c_str(), H5T_NATIVE_DOUBLE, space.get(), H5P_DEFAULT, H5P_DEFAULT,
                       H5P_DEFAULT),
            H5Dclose);
  if (!ds.valid() || H5Dwrite(ds.get(), H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, &v) < 0) {
    fail(name, "cannot write scalar");
  }
  if (units) attr("units", std::string(units), name);
}

template <typename T>
std::vector<T> Location::read_numeric(const std::string& name, hid_t mem_type,
                                      std::vector<hsize_t>* dims_out,
                                      const std::vector<long>& expected, const char* shape) const {
  if (!exists(name)) fail(name, "dataset is missing");
  Handle ds(H5Dopen2(id(), name.c_str(), H5P_DEFAULT), H5Dclose);
  if (!ds.valid()) fail(name, "cannot open dataset (is it a group?)");
  Handle space(H5Dget_space(ds.get()), H5Sclose);
  const int rank = H5Sget_simple_extent_ndims(space.get());
  std::vector<hsize_t> dims(std::max(rank, 0));
  if (rank > 0) H5Sget_simple_extent_dims(space.get(), dims.data(), nullptr);
  bool ok = rank == static_cast<int>(expected.size());
  for (size_t i = 0; ok && i < expected.size(); ++i) {
    if (expected[i] >= 0 && dims[i] != static_cast<hsize_t>(expected[i])) ok = false;
  }
  if (!ok) fail(name, std::string("expected shape ") + shape + ", found " + dims_string(dims));
  Handle ftype(H5Dget_type(ds.get()), H5Tclose);
  if (H5Tget_class(ftype.get()) != H5T_FLOAT && H5Tget_class(ftype.get()) != H5T_INTEGER) {
    fail(name, "expected a numeric dataset");
  }
  // A dataspace claiming more elements than the dataset's bytes in the file can hold (raw, or
  // compressed at deflate's most, 1032:1) is corrupt: refused before the allocation (found by
  // the fuzzers, tests/fuzz).
  double total_d = 1.0;
  for (hsize_t d : dims) total_d *= static_cast<double>(d);
  const double stored = static_cast<double>(H5Dget_storage_size(ds.get()));
  if (total_d * static_cast<double>(sizeof(T)) > 1032.0 * stored + 1024.0)
    fail(name, "the dataset claims " + dims_string(dims) + " elements, more than its " +
                   std::to_string(static_cast<long long>(stored)) +
                   " bytes in the file hold (file corrupt?)");
  hsize_t total = 1;
  for (hsize_t d : dims) total *= d;
  std::vector<T> out(total);
  if (total > 0 && H5Dread(ds.get(), mem_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, out.data()) < 0) {
    fail(name, "cannot read dataset (file truncated or corrupt?)");
  }
  if (dims_out) *dims_out = dims;
  return out;
}

std::vector<double> Location::read_doubles(const std::string& name, std::vector<hsize_t>* dims,
                                           const std::vector<long>& expected,
                                           const char* shape) const {
  return read_numeric<double>(name, H5T_NATIVE_DOUBLE, dims, expected, shape);
}
std::vector<float> Location::read_floats(const std::string& name, std::vector<hsize_t>* dims,
                                         const std::vector<long>& expected,
                                         const char* shape) const {
  return read_numeric<float>(name, H5T_NATIVE_FLOAT, dims, expected, shape);
}
std::vector<int> Location::read_ints(const std::string& name, std::vector<hsize_t>* dims,
                                     const std::vector<long>& expected, const char* shape) const {
  return read_numeric<int>(name, H5T_NATIVE_INT, dims, expected, shape);
}

double Location::read_scalar(const std::string& name) const {
  std::vector<hsize_t> dims;
  return read_doubles(name, &dims, {}, "() (a scalar)").at(0);
}

std::vector<std::string> Location::read_strings(const std::string& name) const {
  if (!exists(name)) fail(name, "dataset is missing");
  Handle ds(H5Dopen2(id(), name.c_str(), H5P_DEFAULT), H5Dclose);
  if (!ds.valid()) fail(name, "cannot open dataset");
  Handle space(H5Dget_space(ds.get()), H5Sclose);
  const hssize_t n = H5Sget_simple_extent_npoints(space.get());
  Handle ftype(H5Dget_type(ds.get()), H5Tclose);
  if (H5Tget_class(ftype.get()) != H5T_STRING || !H5Tis_variable_str(ftype.get())) {
    fail(name, "expected variable-length strings");
  }
  // Every string descriptor takes 16 bytes in the file (compressed at deflate's most, 1032:1).
  hsize_t file_bytes = 0;
  {
    const Handle file(H5Iget_file_id(ds.get()), H5Fclose);
    if (!file.valid() || H5Fget_filesize(file.get(), &file_bytes) < 0) fail(name, "no file size");
  }
  if (n < 0 || static_cast<double>(n) * 16.0 > 1032.0 * static_cast<double>(file_bytes) + 1024.0)
    fail(name, "the dataset claims " + std::to_string(n) + " strings, more than its file holds" +
                   " (file corrupt?)");
  std::vector<std::string> out;
  if (read_vlen_strings_directly(*this, name, ds.get(), static_cast<std::uint64_t>(n), file_bytes,
                                 &out))
    return out;
  std::vector<char*> ptrs(static_cast<size_t>(n), nullptr);
  const Handle t = string_type();
  if (n > 0 && H5Dread(ds.get(), t.get(), H5S_ALL, H5S_ALL, H5P_DEFAULT, ptrs.data()) < 0) {
    fail(name, "cannot read strings (file truncated or corrupt?)");
  }
  for (char* p : ptrs) out.emplace_back(p ? p : "");
  H5Dvlen_reclaim(t.get(), space.get(), H5P_DEFAULT, ptrs.data());
  return out;
}

Handle Location::open_object(const std::string& object) const {
  if (object.empty()) return Handle(H5Oopen(id(), ".", H5P_DEFAULT), H5Oclose);
  return Handle(H5Oopen(id(), object.c_str(), H5P_DEFAULT), H5Oclose);
}

namespace {
void write_attr(const Location& loc, hid_t obj, const std::string& name, hid_t type, hid_t space,
                const void* data) {
  if (H5Aexists(obj, name.c_str()) > 0) H5Adelete(obj, name.c_str());
  Handle a(H5Acreate2(obj, name.c_str(), type, space, H5P_DEFAULT, H5P_DEFAULT), H5Aclose);
  if (!a.valid() || H5Awrite(a.get(), type, data) < 0)
    loc.fail("", "cannot write attribute " + name);
}
}  // namespace

void Location::attr(const std::string& name, const std::string& v,
                    const std::string& object) const {
  // Fixed-length, not variable-length: the text then sits in the attribute's object header,
  // under its checksum, instead of in a global heap that libhdf5 1.10 decodes unchecked (a
  // corrupt heap crashed it: docs/fuzzing.md). h5py reads it as bytes.
  const Handle obj = open_object(object);
  Handle t(H5Tcopy(H5T_C_S1), H5Tclose);
  H5Tset_size(t.get(), v.size() + 1);
  H5Tset_strpad(t.get(), H5T_STR_NULLTERM);
  H5Tset_cset(t.get(), H5T_CSET_UTF8);
  Handle space(H5Screate(H5S_SCALAR), H5Sclose);
  write_attr(*this, obj.get(), name, t.get(), space.get(), v.c_str());
}

void Location::attr(const std::string& name, long v, const std::string& object) const {
  const Handle obj = open_object(object);
  Handle space(H5Screate(H5S_SCALAR), H5Sclose);
  const long long x = v;
  write_attr(*this, obj.get(), name, H5T_NATIVE_LLONG, space.get(), &x);
}

void Location::attr(const std::string& name, double v, const std::string& object) const {
  const Handle obj = open_object(object);
  Handle space(H5Screate(H5S_SCALAR), H5Sclose);
  write_attr(*this, obj.get(), name, H5T_NATIVE_DOUBLE, space.get(), &v);
}

void Location::attr(const std::string& name, const std::vector<double>& v,
                    const std::string& object) const {
  const Handle obj = open_object(object);
  const hsize_t n = v.size();
  Handle space(H5Screate_simple(1, &n, nullptr), H5Sclose);
  write_attr(*this, obj.get(), name, H5T_NATIVE_DOUBLE, space.get(), v.data());
}

std::vector<std::string> Location::member_names() const {
  std::vector<std::string> names;
  Handle plist(H5Gget_create_plist(id()), H5Pclose);
  unsigned flags = 0;
  if (plist.valid()) H5Pget_link_creation_order(plist.get(), &flags);
  const H5_index_t index = (flags & H5P_CRT_ORDER_TRACKED) ? H5_INDEX_CRT_ORDER : H5_INDEX_NAME;
  hsize_t idx = 0;
  const herr_t rc = H5Literate(
      id(), index, H5_ITER_INC, &idx,
      [](hid_t, const char* name, const H5L_info_t*, void* data) -> herr_t {
        static_cast<std::vector<std::string>*>(data)->emplace_back(name);
        return 0;
      },
      &names);
  if (rc < 0) fail("", "cannot list the members");
  return names;
}

bool Location::has_attr(const std::string& name) const { return H5Aexists(id(), name.c_str()) > 0; }

namespace {
Handle open_attr(const Location& loc, const std::string& name) {
  if (H5Aexists(loc.id(), name.c_str()) <= 0) loc.fail("", "attribute '" + name + "' is missing");
  Handle a(H5Aopen(loc.id(), name.c_str(), H5P_DEFAULT), H5Aclose);
  if (!a.valid()) loc.fail("", "cannot open attribute '" + name + "'");
  return a;
}
}  // namespace

std::string Location::attr_string(const std::string& name) const {
  const Handle a = open_attr(*this, name);
  Handle ftype(H5Aget_type(a.get()), H5Tclose);
  if (H5Tget_class(ftype.get()) != H5T_STRING) fail("", "attribute '" + name + "' is not a string");
  if (H5Tis_variable_str(ftype.get())) {
    const Handle t = string_type();
    char* p = nullptr;
    if (H5Aread(a.get(), t.get(), &p) < 0) fail("", "cannot read attribute '" + name + "'");
    std::string s = p ? p : "";
    H5free_memory(p);
    return s;
  }
  const size_t n = H5Tget_size(ftype.get());
  if (n == 0 || n > (1u << 26))
    fail("", "attribute '" + name + "' claims a string of " + std::to_string(n) +
                 " bytes (file corrupt?)");
  std::string s(n, '\0');
  if (H5Aread(a.get(), ftype.get(), s.data()) < 0) fail("", "cannot read attribute '" + name + "'");
  return s.substr(0, s.find('\0'));
}

long Location::attr_long(const std::string& name) const {
  const Handle a = open_attr(*this, name);
  long long x = 0;
  if (H5Aread(a.get(), H5T_NATIVE_LLONG, &x) < 0)
    fail("", "attribute '" + name + "' is not an integer");
  return static_cast<long>(x);
}

double Location::attr_double(const std::string& name) const {
  const Handle a = open_attr(*this, name);
  double x = 0;
  if (H5Aread(a.get(), H5T_NATIVE_DOUBLE, &x) < 0)
    fail("", "attribute '" + name + "' is not a number");
  return x;
}

std::vector<double> Location::attr_doubles(const std::string& name) const {
  const Handle a = open_attr(*this, name);
  Handle space(H5Aget_space(a.get()), H5Sclose);
  const hssize_t n = H5Sget_simple_extent_npoints(space.get());
  std::vector<double> v(static_cast<size_t>(std::max<hssize_t>(n, 0)));
  if (n > 0 && H5Aread(a.get(), H5T_NATIVE_DOUBLE, v.data()) < 0) {
    fail("", "attribute '" + name + "' is not numeric");
  }
  return v;
}

}  // namespace mvtwin::h5
