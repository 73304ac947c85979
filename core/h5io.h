// Thin RAII layer over the HDF5 C API, and the grid layout shared by every file we write.
//
// HDF5 in Debian is not thread-safe: call these from one thread only, after parallel work
// has been reduced.
//
// Grids are stored as datasets of shape [height][width] (or [planes][height][width]) in
// memory order: row 0 is the SOUTHERN row (see grid.h). Each grid dataset carries the
// attributes cell_size_m, origin_x_m, origin_y_m, units and row_order = "south_to_north".
#pragma once

#include <hdf5.h>

#include <cstdint>
#include <string>
#include <vector>

#include "grid.h"

namespace eco::h5 {

/// Owns one HDF5 identifier and closes it with the right H5*close.
class Handle {
public:
    Handle() = default;
    explicit Handle(hid_t id) : id_(id) {}
    Handle(const Handle&) = delete;
    Handle& operator=(const Handle&) = delete;
    Handle(Handle&& o) noexcept : id_(o.id_) { o.id_ = -1; }
    Handle& operator=(Handle&& o) noexcept;
    ~Handle();
    hid_t id() const { return id_; }
    bool valid() const { return id_ >= 0; }

private:
    hid_t id_ = -1;
};

/// An open HDF5 file. Errors throw IoError naming the file and the object.
class File {
public:
    /// Create (truncate) a file for writing.
    static File create(const std::string& path);
    /// Open an existing file read-only; IoError if missing or not HDF5.
    static File openRead(const std::string& path);

    const std::string& path() const { return path_; }
    hid_t id() const { return handle_.id(); }

    bool exists(const std::string& objectPath) const;
    /// Create a group (and its parents) if it does not exist.
    void ensureGroup(const std::string& groupPath);

    void writeF32(const std::string& name, const std::vector<float>& v, const std::vector<hsize_t>& dims);
    void writeF64(const std::string& name, const std::vector<double>& v, const std::vector<hsize_t>& dims);
    void writeI32(const std::string& name, const std::vector<std::int32_t>& v, const std::vector<hsize_t>& dims);
    void writeStrings(const std::string& name, const std::vector<std::string>& v);

    std::vector<float> readF32(const std::string& name, std::vector<hsize_t>* dims = nullptr) const;
    std::vector<double> readF64(const std::string& name, std::vector<hsize_t>* dims = nullptr) const;
    std::vector<std::int32_t> readI32(const std::string& name, std::vector<hsize_t>* dims = nullptr) const;
    std::vector<std::string> readStrings(const std::string& name) const;
    std::vector<hsize_t> shape(const std::string& name) const;
    /// True when the object is a group (false for a dataset); IoError when it does not exist.
    bool isGroup(const std::string& name) const;
    /// True when the dataset stores integers (false for floating point or strings).
    bool isIntegerDataset(const std::string& name) const;

    // Attributes on any object (group or dataset); "/" is the root.
    void setAttr(const std::string& object, const std::string& attr, const std::string& value);
    void setAttr(const std::string& object, const std::string& attr, double value);
    void setAttr(const std::string& object, const std::string& attr, std::int64_t value);
    void setAttr(const std::string& object, const std::string& attr, const std::vector<double>& value);
    bool hasAttr(const std::string& object, const std::string& attr) const;
    std::string attrString(const std::string& object, const std::string& attr) const;
    double attrDouble(const std::string& object, const std::string& attr) const;
    std::int64_t attrInt(const std::string& object, const std::string& attr) const;
    std::vector<double> attrDoubles(const std::string& object, const std::string& attr) const;

    /// Names of the direct children of a group.
    std::vector<std::string> list(const std::string& group) const;

    /// A grid as [height][width] float with the geometry attributes and units.
    void writeGrid(const std::string& name, const Grid<float>& g, const std::string& units);
    Grid<float> readGrid(const std::string& name) const;
    /// Planes of one geometry as [planes][height][width].
    void writeStack(const std::string& name, const std::vector<Grid<float>>& planes,
                    const std::string& units);
    std::vector<Grid<float>> readStack(const std::string& name) const;
    void writeGridI32(const std::string& name, const Grid<std::int32_t>& g, const std::string& units);
    Grid<std::int32_t> readGridI32(const std::string& name) const;

private:
    File(std::string path, hid_t id) : path_(std::move(path)), handle_(id) {}
    void requireObject(const std::string& name) const;
    std::string where(const std::string& object) const;
    std::string path_;
    Handle handle_;
};

}  // namespace eco::h5
