// Thin RAII layer over the HDF5 C API, and the grid layout shared by every file we write.
//
// HDF5 in Debian is not thread-safe: call these from one thread only, after parallel work
// has been reduced.
//
// Grids are stored as datasets of shape [height][width] (or [planes][height][width]) in
// memory order: row 0 is the SOUTHERN row (see grid.h). Each grid dataset carries the
// attributes cell_size_m, origin_x_m, origin_y_m, units and row_order = "south_to_north",
// and HDF5 dimension scales on its axes: x_m and y_m (cell centres, world metres) and, on a
// monthly stack, month (1..12), coordinate datasets beside the grid (docs/hdf5.md).
//
// Every numeric dataset carries a `units` attribute, given by its writer ("1" when the values
// are dimensionless, as in CF conventions).
#pragma once

#include <hdf5.h>

#include <cstdint>
#include <string>
#include <variant>
#include <vector>

#include "grid.h"

namespace eco::h5 {

/// A choice among names, stored as an HDF5 enum: `value` indexes `names`.
struct EnumChoice {
    int value = 0;
    std::vector<std::string> names;
};
/// A typed attribute value: a real, an integer, a boolean (h5py's enum), a choice, text or
/// an array of reals. (Text only as std::string: a bare string literal would convert to bool.)
using AttrValue = std::variant<double, std::int64_t, bool, EnumChoice, std::string, std::vector<double>>;
/// One named, typed attribute, e.g. a model parameter.
struct NamedAttr {
    std::string name;
    AttrValue value;
};

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

    // Numeric datasets with their `units` attribute ("1" for dimensionless values, CF's
    // convention; "m", "m2", "years", ... otherwise).
    void writeF32(const std::string& name, const std::vector<float>& v, const std::vector<hsize_t>& dims,
                  const std::string& units);
    void writeF64(const std::string& name, const std::vector<double>& v, const std::vector<hsize_t>& dims,
                  const std::string& units);
    void writeI32(const std::string& name, const std::vector<std::int32_t>& v, const std::vector<hsize_t>& dims,
                  const std::string& units);
    void writeI64(const std::string& name, const std::vector<std::int64_t>& v, const std::vector<hsize_t>& dims,
                  const std::string& units);
    /// Bytes (an encoded file kept in a checkpoint, ...).
    void writeU8(const std::string& name, const std::vector<std::uint8_t>& v, const std::vector<hsize_t>& dims,
                 const std::string& units);
    /// A list of names (fixed-length UTF-8 strings); no units.
    void writeStrings(const std::string& name, const std::vector<std::string>& v);

    std::vector<float> readF32(const std::string& name, std::vector<hsize_t>* dims = nullptr) const;
    std::vector<double> readF64(const std::string& name, std::vector<hsize_t>* dims = nullptr) const;
    std::vector<std::int32_t> readI32(const std::string& name, std::vector<hsize_t>* dims = nullptr) const;
    /// Any integer dataset as int64.
    std::vector<std::int64_t> readI64(const std::string& name, std::vector<hsize_t>* dims = nullptr) const;
    std::vector<std::string> readStrings(const std::string& name) const;
    std::vector<std::uint8_t> readU8(const std::string& name, std::vector<hsize_t>* dims = nullptr) const;
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
    /// An array of strings (fixed-length UTF-8, NUL-padded to the longest).
    void setAttr(const std::string& object, const std::string& attr, const std::vector<std::string>& value);
    /// A boolean as h5py writes one: an HDF5 enum of int8 {FALSE = 0, TRUE = 1}.
    void setAttrBool(const std::string& object, const std::string& attr, bool value);
    /// A choice among names: an HDF5 enum of int32 whose members are `names` with values
    /// 0, 1, ...; `value` indexes `names`.
    void setAttrEnum(const std::string& object, const std::string& attr, int value, const std::vector<std::string>& names);
    /// A typed attribute of any kind (NamedAttr).
    void setAttr(const std::string& object, const NamedAttr& a);
    bool hasAttr(const std::string& object, const std::string& attr) const;
    /// True when the attribute is stored as text (files written before typed attributes).
    bool attrIsString(const std::string& object, const std::string& attr) const;
    std::string attrString(const std::string& object, const std::string& attr) const;
    double attrDouble(const std::string& object, const std::string& attr) const;
    /// An integer attribute; an enum (a boolean, a choice) gives its member's value.
    std::int64_t attrInt(const std::string& object, const std::string& attr) const;
    /// A boolean: an enum or integer attribute (non-zero is true), or the text "true"/"false"
    /// of files written before typed attributes.
    bool attrBool(const std::string& object, const std::string& attr) const;
    /// The member name of an enum attribute, or the text of a string attribute.
    std::string attrEnumName(const std::string& object, const std::string& attr) const;
    std::vector<double> attrDoubles(const std::string& object, const std::string& attr) const;

    /// Names of the direct children of a group.
    std::vector<std::string> list(const std::string& group) const;

    /// A grid as [height][width] float with the geometry attributes and units.
    void writeGrid(const std::string& name, const Grid<float>& g, const std::string& units);
    Grid<float> readGrid(const std::string& name) const;
    /// Planes of one geometry as [planes][height][width]; 12 planes are months (a month scale
    /// 1..12 on the first axis), any other count planes (a plane scale 0..n-1).
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
