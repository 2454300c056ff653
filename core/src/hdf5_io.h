#pragma once
// Internal: a thin RAII layer over the HDF5 C API that turns every failure into an
// mvtwin::Error naming the file and the object. Used by the file formats of core/.
#include <hdf5.h>

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace mvtwin::h5 {

/// Owns an HDF5 identifier and closes it with the matching H5?close.
class Handle {
 public:
  Handle() = default;
  Handle(hid_t id, herr_t (*close)(hid_t)) : id_(id), close_(close) {}
  Handle(Handle&& o) noexcept : id_(o.id_), close_(o.close_) { o.id_ = H5I_INVALID_HID; }
  Handle& operator=(Handle&& o) noexcept;
  Handle(const Handle&) = delete;
  Handle& operator=(const Handle&) = delete;
  ~Handle() { reset(); }
  void reset();
  hid_t get() const { return id_; }
  bool valid() const { return id_ >= 0; }

 private:
  hid_t id_ = H5I_INVALID_HID;
  herr_t (*close_)(hid_t) = nullptr;
};

/// An open file (or a group inside one) with the file name kept for error messages.
class Location {
 public:
  Location(Handle h, std::string file, std::string path)
      : h_(std::move(h)), file_(std::move(file)), path_(std::move(path)) {}

  static Location create_file(const std::filesystem::path& path);
  static Location open_file(const std::filesystem::path& path);

  hid_t id() const { return h_.get(); }
  const std::string& file() const { return file_; }
  const std::string& path() const { return path_; }
  std::string full(const std::string& name) const {
    return path_ == "/" ? "/" + name : path_ + "/" + name;
  }
  [[noreturn]] void fail(const std::string& name, const std::string& problem) const;

  /// `track_order` keeps the creation order of members (for ordered records).
  Location create_group(const std::string& name, bool track_order = false) const;
  Location open_group(const std::string& name) const;
  bool exists(const std::string& name) const;
  /// Names of the members of this group, in creation order when the group tracks it.
  std::vector<std::string> member_names() const;

  // Datasets: row-major data with explicit dimensions.
  void write(const std::string& name, const std::vector<double>& data,
             const std::vector<hsize_t>& dims, const char* units = nullptr) const;
  void write(const std::string& name, const std::vector<float>& data,
             const std::vector<hsize_t>& dims, bool compress) const;
  void write(const std::string& name, const std::vector<std::uint8_t>& data,
             const std::vector<hsize_t>& dims) const;
  void write(const std::string& name, const std::vector<int>& data,
             const std::vector<hsize_t>& dims) const;
  void write_strings(const std::string& name, const std::vector<std::string>& s) const;
  void write_scalar(const std::string& name, double v, const char* units) const;

  /// Reads a dataset, checking its rank and (where expected[i] >= 0) each dimension;
  /// `shape` names the expected shape in messages, e.g. "(F, 9, 3)".
  std::vector<double> read_doubles(const std::string& name, std::vector<hsize_t>* dims,
                                   const std::vector<long>& expected, const char* shape) const;
  std::vector<float> read_floats(const std::string& name, std::vector<hsize_t>* dims,
                                 const std::vector<long>& expected, const char* shape) const;
  std::vector<int> read_ints(const std::string& name, std::vector<hsize_t>* dims,
                             const std::vector<long>& expected, const char* shape) const;
  std::vector<std::string> read_strings(const std::string& name) const;
  double read_scalar(const std::string& name) const;

  // Attributes of this location (or of a dataset under it when `object` is not empty).
  void attr(const std::string& name, const std::string& v, const std::string& object = "") const;
  void attr(const std::string& name, long v, const std::string& object = "") const;
  void attr(const std::string& name, double v, const std::string& object = "") const;
  void attr(const std::string& name, const std::vector<double>& v,
            const std::string& object = "") const;
  bool has_attr(const std::string& name) const;
  std::string attr_string(const std::string& name) const;
  long attr_long(const std::string& name) const;
  double attr_double(const std::string& name) const;
  std::vector<double> attr_doubles(const std::string& name) const;

 private:
  Handle open_object(const std::string& object) const;
  template <typename T>
  std::vector<T> read_numeric(const std::string& name, hid_t mem_type, std::vector<hsize_t>* dims,
                              const std::vector<long>& expected, const char* shape) const;
  Handle h_;
  std::string file_;
  std::string path_;
};

}  // namespace mvtwin::h5
