#include "hdf5_io.h"

#include <cmath>
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
  const hid_t id = H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
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
  std::vector<char*> ptrs(static_cast<size_t>(std::max<hssize_t>(n, 0)), nullptr);
  const Handle t = string_type();
  if (n > 0 && H5Dread(ds.get(), t.get(), H5S_ALL, H5S_ALL, H5P_DEFAULT, ptrs.data()) < 0) {
    fail(name, "cannot read strings");
  }
  std::vector<std::string> out;
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
  const Handle obj = open_object(object);
  const Handle t = string_type();
  Handle space(H5Screate(H5S_SCALAR), H5Sclose);
  const char* p = v.c_str();
  write_attr(*this, obj.get(), name, t.get(), space.get(), &p);
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
