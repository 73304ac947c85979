#include "h5io.h"
#include "text_format.h"

#include <hdf5_hl.h>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <numeric>
#include <sstream>
#include <type_traits>

#include "memory.h"
#include "provenance.h"

namespace eco::h5 {

namespace {

/// HDF5 prints its own error stack to stderr by default; we report errors ourselves.
struct SilenceHdf5 {
    SilenceHdf5() { H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr); }
};
const SilenceHdf5 kSilence;

hid_t closeAny(hid_t id) {
    switch (H5Iget_type(id)) {
        case H5I_FILE: return H5Fclose(id);
        case H5I_GROUP: return H5Gclose(id);
        case H5I_DATASET: return H5Dclose(id);
        case H5I_DATASPACE: return H5Sclose(id);
        case H5I_DATATYPE: return H5Tclose(id);
        case H5I_ATTR: return H5Aclose(id);
        case H5I_GENPROP_LST: return H5Pclose(id);
        default: return 0;
    }
}

std::size_t product(const std::vector<hsize_t>& dims) {
    return std::accumulate(dims.begin(), dims.end(), std::size_t{1},
                           [](std::size_t a, hsize_t b) { return a * static_cast<std::size_t>(b); });
}

/// A creation property list of `cls` without object modification times: HDF5 stamps every
/// group and dataset with the time it was written unless told not to, which alone makes two
/// runs of the same inputs differ in bytes (docs/hdf5.md "Byte-identical outputs").
Handle untimedCreationList(hid_t cls) {
    Handle plist(H5Pcreate(cls));
    H5Pset_obj_track_times(plist.id(), false);
    return plist;
}

/// The number of elements of a dataset or attribute of shape `dims` read from a file, checked
/// against memory before a buffer is allocated for it: a damaged file may declare any shape
/// (a product of sizes that overflows, or 10^12 elements), which was a std::bad_alloc or a
/// std::length_error escaping as an internal error.
std::size_t elementsToRead(const std::vector<hsize_t>& dims, double elementBytes, const std::string& what) {
    double n = 1;
    for (hsize_t d : dims) n *= static_cast<double>(d);
    requireMemory(n * elementBytes, what + " (shape of " + formatNumber(n, 10) + " elements; a damaged file?)", "");
    return static_cast<std::size_t>(n);  // exact: it fits in memory, so well below 2^53
}

std::string parentOf(const std::string& path) {
    const auto pos = path.find_last_of('/');
    if (pos == std::string::npos || pos == 0) return "/";
    return path.substr(0, pos);
}

}  // namespace

Handle& Handle::operator=(Handle&& o) noexcept {
    if (this != &o) {
        if (id_ >= 0) closeAny(id_);
        id_ = o.id_;
        o.id_ = -1;
    }
    return *this;
}

Handle::~Handle() {
    if (id_ >= 0) closeAny(id_);
}

File File::create(const std::string& path) {
    // The file creation list is also the root group's: no modification time on it either.
    const Handle fcpl = untimedCreationList(H5P_FILE_CREATE);
    // The HDF5 1.10 file format, low and high bound: its superblock, object headers and chunk
    // indexes carry checksums that the library verifies on reading, so a damaged file is
    // refused with an error instead of being parsed (HDF5 1.10.8 itself crashes on some
    // damaged metadata of the older format: docs/robustness.md). Pinning the high bound
    // keeps the bytes the same with a newer library. Every HDF5 since 1.10 (2016), h5py and
    // R's hdf5r read it.
    const Handle fapl(H5Pcreate(H5P_FILE_ACCESS));
    H5Pset_libver_bounds(fapl.id(), H5F_LIBVER_V110, H5F_LIBVER_V110);
    const hid_t id = H5Fcreate(path.c_str(), H5F_ACC_TRUNC, fcpl.id(), fapl.id());
    if (id < 0) throw IoError(path + ": cannot create HDF5 file");
    return File(path, id);
}

namespace {
std::uintmax_t fileSizeOrZero(const std::string& path) {
    std::error_code ec;
    const std::uintmax_t n = std::filesystem::file_size(path, ec);
    return ec ? 0 : n;
}
}  // namespace

File File::openRead(const std::string& path) {
    if (std::FILE* probe = std::fopen(path.c_str(), "rb")) std::fclose(probe);
    else throw IoError(path + ": cannot open file (missing or unreadable)");
    if (H5Fis_hdf5(path.c_str()) <= 0) throw IoError(path + ": not an HDF5 file (or corrupt)");
    const hid_t id = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
    // An HDF5 signature that does not open: usually a file cut short (an interrupted copy,
    // download or write), which said only "cannot open HDF5 file".
    if (id < 0)
        throw IoError(path + ": cannot open HDF5 file: truncated or damaged (" + std::to_string(fileSizeOrZero(path)) +
                      " bytes; an interrupted copy, download or write?), or locked by a program writing it");
    noteInputFile(path);
    return File(path, id);
}

std::string File::where(const std::string& object) const { return path_ + ": " + object; }

bool File::exists(const std::string& objectPath) const {
    if (objectPath == "/") return true;
    // Check each level: H5Lexists fails on a missing intermediate group.
    std::string sofar;
    std::stringstream ss(objectPath);
    std::string part;
    while (std::getline(ss, part, '/')) {
        if (part.empty()) continue;
        sofar += "/" + part;
        if (H5Lexists(id(), sofar.c_str(), H5P_DEFAULT) <= 0) return false;
    }
    return true;
}

void File::ensureGroup(const std::string& groupPath) {
    std::string sofar;
    std::stringstream ss(groupPath);
    std::string part;
    while (std::getline(ss, part, '/')) {
        if (part.empty()) continue;
        sofar += "/" + part;
        if (H5Lexists(id(), sofar.c_str(), H5P_DEFAULT) > 0) continue;
        const Handle gcpl = untimedCreationList(H5P_GROUP_CREATE);
        Handle g(H5Gcreate2(id(), sofar.c_str(), H5P_DEFAULT, gcpl.id(), H5P_DEFAULT));
        if (!g.valid()) throw IoError(where(sofar) + ": cannot create group");
    }
}

void File::requireObject(const std::string& name) const {
    if (!exists(name)) throw IoError(where(name) + ": dataset or group is missing");
}

namespace {

/// The largest dataset kept in its object header (compact layout; HDF5 allows 64 KB).
constexpr std::size_t kCompactMaxBytes = 32 * 1024;

/// The storage of a dataset too small to be compressed: in its object header (compact) up to
/// kCompactMaxBytes, where the HDF5 1.10 format's header checksum covers the values too,
/// else chunked with Fletcher-32. Contiguous storage (HDF5's default) has no checksum, so a
/// damaged byte in a small table or a list of names was read back as another value.
void setSmallLayout(hid_t plist, std::size_t bytes, std::size_t elementBytes = 0, hsize_t elements = 0) {
    if (bytes <= kCompactMaxBytes) {
        H5Pset_layout(plist, H5D_COMPACT);
        return;
    }
    const hsize_t chunk = std::max<hsize_t>(1, std::min<hsize_t>(elements, 65536 / std::max<std::size_t>(1, elementBytes)));
    H5Pset_chunk(plist, 1, &chunk);
    H5Pset_fletcher32(plist);
}

template <typename T>
void writeTyped(File& f, const std::string& name, const T* data, std::size_t n,
                const std::vector<hsize_t>& dims, hid_t memType, hid_t fileType, const std::string& units) {
    if (product(dims) != n)
        throw ValidationError(f.path() + ": " + name + ": data size does not match its shape");
    f.ensureGroup(parentOf(name));
    Handle space(H5Screate_simple(static_cast<int>(dims.size()), dims.data(), nullptr));
    Handle plist = untimedCreationList(H5P_DATASET_CREATE);
    // Compress large datasets; chunk along the first axis.
    if (n >= 4096 && !dims.empty()) {
        std::vector<hsize_t> chunk = dims;
        chunk[0] = 1;
        if (dims.size() == 1) chunk[0] = std::min<hsize_t>(dims[0], 65536);
        else if (dims.size() == 2) chunk[0] = std::max<hsize_t>(1, std::min<hsize_t>(dims[0], 65536 / std::max<hsize_t>(1, dims[1])));
        H5Pset_chunk(plist.id(), static_cast<int>(chunk.size()), chunk.data());
        H5Pset_shuffle(plist.id());
        H5Pset_deflate(plist.id(), 4);
        // A checksum of each compressed chunk: damage to the data itself (which the
        // metadata checksums do not cover) is an error on reading, not wrong values.
        H5Pset_fletcher32(plist.id());
    } else {
        setSmallLayout(plist.id(), n * sizeof(T));
    }
    if (H5Lexists(f.id(), name.c_str(), H5P_DEFAULT) > 0) H5Ldelete(f.id(), name.c_str(), H5P_DEFAULT);
    Handle ds(H5Dcreate2(f.id(), name.c_str(), fileType, space.id(), H5P_DEFAULT, plist.id(), H5P_DEFAULT));
    if (!ds.valid()) throw IoError(f.path() + ": " + name + ": cannot create dataset");
    if (n > 0 && H5Dwrite(ds.id(), memType, H5S_ALL, H5S_ALL, H5P_DEFAULT, data) < 0)
        throw IoError(f.path() + ": " + name + ": cannot write dataset");
    ds = Handle();
    f.setAttr(name, "units", units);
}

template <typename T>
std::vector<T> readTyped(const File& f, const std::string& name, std::vector<hsize_t>* dimsOut,
                         hid_t memType, H5T_class_t expectClass) {
    if (!f.exists(name)) throw IoError(f.path() + ": " + name + ": dataset is missing");
    Handle ds(H5Dopen2(f.id(), name.c_str(), H5P_DEFAULT));
    if (!ds.valid()) throw IoError(f.path() + ": " + name + ": not a dataset");
    Handle type(H5Dget_type(ds.id()));
    if (H5Tget_class(type.id()) != expectClass)
        throw IoError(f.path() + ": " + name + ": dataset has the wrong element type");
    Handle space(H5Dget_space(ds.id()));
    const int rank = H5Sget_simple_extent_ndims(space.id());
    std::vector<hsize_t> dims(static_cast<std::size_t>(std::max(rank, 0)));
    H5Sget_simple_extent_dims(space.id(), dims.data(), nullptr);
    std::vector<T> out(elementsToRead(dims, sizeof(T), f.path() + ": " + name));
    if (!out.empty() && H5Dread(ds.id(), memType, H5S_ALL, H5S_ALL, H5P_DEFAULT, out.data()) < 0)
        throw IoError(f.path() + ": " + name + ": cannot read dataset (corrupt file?)");
    if (dimsOut) *dimsOut = dims;
    return out;
}

}  // namespace

void File::writeF32(const std::string& name, const std::vector<float>& v, const std::vector<hsize_t>& dims,
                    const std::string& units) {
    writeTyped(*this, name, v.data(), v.size(), dims, H5T_NATIVE_FLOAT, H5T_IEEE_F32LE, units);
}
void File::writeF64(const std::string& name, const std::vector<double>& v, const std::vector<hsize_t>& dims,
                    const std::string& units) {
    writeTyped(*this, name, v.data(), v.size(), dims, H5T_NATIVE_DOUBLE, H5T_IEEE_F64LE, units);
}
void File::writeI32(const std::string& name, const std::vector<std::int32_t>& v, const std::vector<hsize_t>& dims,
                    const std::string& units) {
    writeTyped(*this, name, v.data(), v.size(), dims, H5T_NATIVE_INT32, H5T_STD_I32LE, units);
}
void File::writeI64(const std::string& name, const std::vector<std::int64_t>& v, const std::vector<hsize_t>& dims,
                    const std::string& units) {
    writeTyped(*this, name, v.data(), v.size(), dims, H5T_NATIVE_INT64, H5T_STD_I64LE, units);
}
void File::writeU8(const std::string& name, const std::vector<std::uint8_t>& v, const std::vector<hsize_t>& dims,
                   const std::string& units) {
    writeTyped(*this, name, v.data(), v.size(), dims, H5T_NATIVE_UINT8, H5T_STD_U8LE, units);
}

std::vector<float> File::readF32(const std::string& name, std::vector<hsize_t>* dims) const {
    return readTyped<float>(*this, name, dims, H5T_NATIVE_FLOAT, H5T_FLOAT);
}
std::vector<double> File::readF64(const std::string& name, std::vector<hsize_t>* dims) const {
    return readTyped<double>(*this, name, dims, H5T_NATIVE_DOUBLE, H5T_FLOAT);
}
std::vector<std::int32_t> File::readI32(const std::string& name, std::vector<hsize_t>* dims) const {
    return readTyped<std::int32_t>(*this, name, dims, H5T_NATIVE_INT32, H5T_INTEGER);
}
std::vector<std::int64_t> File::readI64(const std::string& name, std::vector<hsize_t>* dims) const {
    return readTyped<std::int64_t>(*this, name, dims, H5T_NATIVE_INT64, H5T_INTEGER);
}

std::vector<std::uint8_t> File::readU8(const std::string& name, std::vector<hsize_t>* dims) const {
    return readTyped<std::uint8_t>(*this, name, dims, H5T_NATIVE_UINT8, H5T_INTEGER);
}

std::vector<hsize_t> File::shape(const std::string& name) const {
    requireObject(name);
    Handle ds(H5Dopen2(id(), name.c_str(), H5P_DEFAULT));
    if (!ds.valid()) throw IoError(where(name) + ": not a dataset");
    Handle space(H5Dget_space(ds.id()));
    const int rank = H5Sget_simple_extent_ndims(space.id());
    std::vector<hsize_t> dims(static_cast<std::size_t>(std::max(rank, 0)));
    H5Sget_simple_extent_dims(space.id(), dims.data(), nullptr);
    return dims;
}

bool File::isGroup(const std::string& name) const {
    requireObject(name);
    Handle o(H5Oopen(id(), name.c_str(), H5P_DEFAULT));
    if (!o.valid()) throw IoError(where(name) + ": cannot open");
    return H5Iget_type(o.id()) == H5I_GROUP;
}

bool File::isIntegerDataset(const std::string& name) const {
    requireObject(name);
    Handle ds(H5Dopen2(id(), name.c_str(), H5P_DEFAULT));
    if (!ds.valid()) throw IoError(where(name) + ": not a dataset");
    Handle type(H5Dget_type(ds.id()));
    return H5Tget_class(type.id()) == H5T_INTEGER;
}

void File::writeStrings(const std::string& name, const std::vector<std::string>& v) {
    ensureGroup(parentOf(name));
    // Fixed-length strings, each padded with NULs to the longest (at least 1 byte): a
    // variable-length string keeps its bytes in the file's global heap, which carries no
    // checksum, and HDF5 1.10.8 allocates whatever length a damaged heap declares (4 GB from
    // one flipped byte, found by fuzz_canopy_file). Fixed-length data lives in the dataset
    // itself, its type and size in the checksummed object header.
    std::size_t width = 1;
    for (const auto& s : v) width = std::max(width, s.size());
    std::vector<char> bytes(v.size() * width, '\0');
    for (std::size_t i = 0; i < v.size(); ++i) std::copy(v[i].begin(), v[i].end(), bytes.begin() + static_cast<std::ptrdiff_t>(i * width));
    Handle type(H5Tcopy(H5T_C_S1));
    H5Tset_size(type.id(), width);
    H5Tset_strpad(type.id(), H5T_STR_NULLPAD);
    H5Tset_cset(type.id(), H5T_CSET_UTF8);
    const hsize_t n = v.size();
    Handle space(H5Screate_simple(1, &n, nullptr));
    if (H5Lexists(id(), name.c_str(), H5P_DEFAULT) > 0) H5Ldelete(id(), name.c_str(), H5P_DEFAULT);
    const Handle dcpl = untimedCreationList(H5P_DATASET_CREATE);
    setSmallLayout(dcpl.id(), bytes.size(), width, n);
    Handle ds(H5Dcreate2(id(), name.c_str(), type.id(), space.id(), H5P_DEFAULT, dcpl.id(), H5P_DEFAULT));
    if (!ds.valid()) throw IoError(where(name) + ": cannot create string dataset");
    if (n > 0 && H5Dwrite(ds.id(), type.id(), H5S_ALL, H5S_ALL, H5P_DEFAULT, bytes.data()) < 0)
        throw IoError(where(name) + ": cannot write string dataset");
}

std::vector<std::string> File::readStrings(const std::string& name) const {
    requireObject(name);
    Handle ds(H5Dopen2(id(), name.c_str(), H5P_DEFAULT));
    if (!ds.valid()) throw IoError(where(name) + ": not a dataset");
    Handle ftype(H5Dget_type(ds.id()));
    if (H5Tget_class(ftype.id()) != H5T_STRING) throw IoError(where(name) + ": not a string dataset");
    Handle space(H5Dget_space(ds.id()));
    // One dimension only: the sizes are written into n (a 2-D dataset wrote past it).
    if (H5Sget_simple_extent_ndims(space.id()) != 1) throw IoError(where(name) + ": not a one-dimensional string dataset");
    hsize_t n = 0;
    H5Sget_simple_extent_dims(space.id(), &n, nullptr);
    n = elementsToRead({n}, sizeof(char*) + sizeof(std::string), where(name));
    std::vector<std::string> out;
    if (H5Tis_variable_str(ftype.id()) <= 0) {
        // Fixed-length (what writeStrings writes): n strings of `width` bytes, NUL-padded or
        // NUL-terminated; a space-padded string keeps its spaces, as h5py shows them.
        const std::size_t width = H5Tget_size(ftype.id());
        if (width == 0) throw IoError(where(name) + ": string dataset of width 0");
        elementsToRead({n, width}, 1, where(name));
        std::vector<char> bytes(n * width);
        Handle mem(H5Tcopy(ftype.id()));
        if (n > 0 && H5Dread(ds.id(), mem.id(), H5S_ALL, H5S_ALL, H5P_DEFAULT, bytes.data()) < 0)
            throw IoError(where(name) + ": cannot read string dataset");
        out.reserve(n);
        for (std::size_t i = 0; i < n; ++i) {
            const char* b = bytes.data() + i * width;
            out.emplace_back(b, static_cast<std::size_t>(std::find(b, b + width, '\0') - b));
        }
        return out;
    }
    // Variable-length: files written before fixed-length strings (their bytes in the global
    // heap; a damaged heap is not detected, see writeStrings).
    Handle type(H5Tcopy(H5T_C_S1));
    H5Tset_size(type.id(), H5T_VARIABLE);
    H5Tset_cset(type.id(), H5Tget_cset(ftype.id()));
    std::vector<char*> ptrs(n, nullptr);
    if (n > 0 && H5Dread(ds.id(), type.id(), H5S_ALL, H5S_ALL, H5P_DEFAULT, ptrs.data()) < 0)
        throw IoError(where(name) + ": cannot read string dataset");
    out.reserve(n);
    for (char* p : ptrs) out.emplace_back(p ? p : "");
    if (n > 0) H5Dvlen_reclaim(type.id(), space.id(), H5P_DEFAULT, ptrs.data());
    return out;
}

namespace {

Handle openObject(const File& f, const std::string& object) {
    if (!f.exists(object)) throw IoError(f.path() + ": " + object + ": object is missing");
    Handle o(H5Oopen(f.id(), object.c_str(), H5P_DEFAULT));
    if (!o.valid()) throw IoError(f.path() + ": " + object + ": cannot open object");
    return o;
}

void writeAttr(const File& f, const std::string& object, const std::string& attr, hid_t type,
               hid_t space, const void* data) {
    // H5Oopen returns a group or dataset id; close it with H5Oclose through Handle's H5Iget_type.
    Handle o = openObject(f, object);
    if (H5Aexists(o.id(), attr.c_str()) > 0) H5Adelete(o.id(), attr.c_str());
    Handle a(H5Acreate2(o.id(), attr.c_str(), type, space, H5P_DEFAULT, H5P_DEFAULT));
    const bool empty = H5Sget_simple_extent_type(space) == H5S_NULL;  // nothing to write
    if (!a.valid() || (!empty && H5Awrite(a.id(), type, data) < 0))
        throw IoError(f.path() + ": " + object + ": cannot write attribute " + attr);
}

Handle openAttr(const File& f, const std::string& object, const std::string& attr, Handle& obj) {
    obj = openObject(f, object);
    if (H5Aexists(obj.id(), attr.c_str()) <= 0)
        throw IoError(f.path() + ": " + object + ": attribute '" + attr + "' is missing");
    return Handle(H5Aopen(obj.id(), attr.c_str(), H5P_DEFAULT));
}

}  // namespace

void File::setAttr(const std::string& object, const std::string& attr, const std::string& value) {
    Handle type(H5Tcopy(H5T_C_S1));
    H5Tset_size(type.id(), value.size() + 1);
    H5Tset_cset(type.id(), H5T_CSET_UTF8);
    Handle space(H5Screate(H5S_SCALAR));
    writeAttr(*this, object, attr, type.id(), space.id(), value.c_str());
}

void File::setAttr(const std::string& object, const std::string& attr, double value) {
    Handle space(H5Screate(H5S_SCALAR));
    writeAttr(*this, object, attr, H5T_NATIVE_DOUBLE, space.id(), &value);
}

void File::setAttr(const std::string& object, const std::string& attr, std::int64_t value) {
    Handle space(H5Screate(H5S_SCALAR));
    writeAttr(*this, object, attr, H5T_NATIVE_INT64, space.id(), &value);
}

void File::setAttr(const std::string& object, const std::string& attr, const std::vector<double>& value) {
    const hsize_t n = value.size();
    Handle space(H5Screate_simple(1, &n, nullptr));
    writeAttr(*this, object, attr, H5T_NATIVE_DOUBLE, space.id(), value.data());
}

void File::setAttr(const std::string& object, const std::string& attr, const std::vector<std::string>& value) {
    std::size_t width = 1;
    for (const auto& v : value) width = std::max(width, v.size());
    std::vector<char> bytes(value.size() * width, '\0');
    for (std::size_t i = 0; i < value.size(); ++i)
        std::copy(value[i].begin(), value[i].end(), bytes.begin() + static_cast<std::ptrdiff_t>(i * width));
    Handle type(H5Tcopy(H5T_C_S1));
    H5Tset_size(type.id(), width);
    H5Tset_strpad(type.id(), H5T_STR_NULLPAD);
    H5Tset_cset(type.id(), H5T_CSET_UTF8);
    const hsize_t n = value.size();
    // An empty list: HDF5's null dataspace (an attribute cannot have a dimension of size 0).
    Handle space(n > 0 ? H5Screate_simple(1, &n, nullptr) : H5Screate(H5S_NULL));
    writeAttr(*this, object, attr, type.id(), space.id(), bytes.data());
}

void File::setAttrBool(const std::string& object, const std::string& attr, bool value) {
    // h5py's boolean: an enum on int8 with members FALSE and TRUE (numpy bool on reading).
    Handle type(H5Tenum_create(H5T_NATIVE_INT8));
    const std::int8_t no = 0, yes = 1;
    H5Tenum_insert(type.id(), "FALSE", &no);
    H5Tenum_insert(type.id(), "TRUE", &yes);
    const std::int8_t v = value ? yes : no;
    Handle space(H5Screate(H5S_SCALAR));
    writeAttr(*this, object, attr, type.id(), space.id(), &v);
}

void File::setAttrEnum(const std::string& object, const std::string& attr, int value, const std::vector<std::string>& names) {
    if (value < 0 || static_cast<std::size_t>(value) >= names.size())
        throw ValidationError(where(object) + ": attribute " + attr + ": value " + std::to_string(value) + " is not one of " +
                              std::to_string(names.size()) + " choices");
    Handle type(H5Tenum_create(H5T_NATIVE_INT32));
    for (std::size_t i = 0; i < names.size(); ++i) {
        const std::int32_t member = static_cast<std::int32_t>(i);
        H5Tenum_insert(type.id(), names[i].c_str(), &member);
    }
    const std::int32_t v = value;
    Handle space(H5Screate(H5S_SCALAR));
    writeAttr(*this, object, attr, type.id(), space.id(), &v);
}

void File::setAttr(const std::string& object, const NamedAttr& a) {
    std::visit(
        [&](const auto& v) {
            using V = std::decay_t<decltype(v)>;
            if constexpr (std::is_same_v<V, bool>) setAttrBool(object, a.name, v);
            else if constexpr (std::is_same_v<V, EnumChoice>) setAttrEnum(object, a.name, v.value, v.names);
            else setAttr(object, a.name, v);
        },
        a.value);
}

bool File::hasAttr(const std::string& object, const std::string& attr) const {
    if (!exists(object)) return false;
    Handle o(H5Oopen(id(), object.c_str(), H5P_DEFAULT));
    return o.valid() && H5Aexists(o.id(), attr.c_str()) > 0;
}

bool File::attrIsString(const std::string& object, const std::string& attr) const {
    Handle obj;
    Handle a = openAttr(*this, object, attr, obj);
    Handle type(H5Aget_type(a.id()));
    return H5Tget_class(type.id()) == H5T_STRING;
}

std::string File::attrString(const std::string& object, const std::string& attr) const {
    Handle obj;
    Handle a = openAttr(*this, object, attr, obj);
    Handle type(H5Aget_type(a.id()));
    if (H5Tget_class(type.id()) != H5T_STRING)
        throw IoError(where(object) + ": attribute '" + attr + "' is not a string");
    if (H5Tis_variable_str(type.id()) > 0) {
        char* p = nullptr;
        Handle mem(H5Tcopy(H5T_C_S1));
        H5Tset_size(mem.id(), H5T_VARIABLE);
        H5Tset_cset(mem.id(), H5Tget_cset(type.id()));
        if (H5Aread(a.id(), mem.id(), &p) < 0) throw IoError(where(object) + ": cannot read attribute " + attr);
        std::string s = p ? p : "";
        H5free_memory(p);
        return s;
    }
    const std::size_t n = elementsToRead({H5Tget_size(type.id())}, 1, where(object) + ": attribute " + attr);
    std::string s(n, '\0');
    if (H5Aread(a.id(), type.id(), s.data()) < 0) throw IoError(where(object) + ": cannot read attribute " + attr);
    s.resize(s.find('\0') == std::string::npos ? n : s.find('\0'));
    return s;
}

namespace {

/// The value of a scalar enum attribute as an integer (its member's value).
std::int64_t enumValue(hid_t a, hid_t fileType, const std::string& what) {
    Handle mem(H5Tget_native_type(fileType, H5T_DIR_ASCEND));
    Handle base(H5Tget_super(mem.id()));
    unsigned char raw[8] = {0};  // room for the widest base (and for int64 after conversion)
    if (!base.valid() || H5Tget_size(mem.id()) > sizeof raw || H5Aread(a, mem.id(), raw) < 0)
        throw IoError(what + ": cannot read enum attribute");
    // Widen from the enum's base integer type to int64.
    if (H5Tconvert(base.id(), H5T_NATIVE_INT64, 1, raw, nullptr, H5P_DEFAULT) < 0)
        throw IoError(what + ": cannot convert enum attribute");
    std::int64_t v = 0;
    std::memcpy(&v, raw, sizeof v);
    return v;
}

}  // namespace

double File::attrDouble(const std::string& object, const std::string& attr) const {
    Handle obj;
    Handle a = openAttr(*this, object, attr, obj);
    Handle type(H5Aget_type(a.id()));
    if (H5Tget_class(type.id()) == H5T_ENUM)
        return static_cast<double>(enumValue(a.id(), type.id(), where(object) + ": attribute " + attr));
    double v = 0;
    if (H5Aread(a.id(), H5T_NATIVE_DOUBLE, &v) < 0) throw IoError(where(object) + ": cannot read attribute " + attr);
    return v;
}


std::int64_t File::attrInt(const std::string& object, const std::string& attr) const {
    Handle obj;
    Handle a = openAttr(*this, object, attr, obj);
    Handle type(H5Aget_type(a.id()));
    if (H5Tget_class(type.id()) == H5T_ENUM) return enumValue(a.id(), type.id(), where(object) + ": attribute " + attr);
    std::int64_t v = 0;
    if (H5Aread(a.id(), H5T_NATIVE_INT64, &v) < 0) throw IoError(where(object) + ": cannot read attribute " + attr);
    return v;
}

bool File::attrBool(const std::string& object, const std::string& attr) const {
    Handle obj;
    Handle a = openAttr(*this, object, attr, obj);
    Handle type(H5Aget_type(a.id()));
    if (H5Tget_class(type.id()) == H5T_STRING) {
        const std::string text = attrString(object, attr);
        if (text == "true" || text == "1") return true;
        if (text == "false" || text == "0") return false;
        throw IoError(where(object) + ": attribute " + attr + " = '" + text + "' is not true or false");
    }
    return attrInt(object, attr) != 0;
}

std::string File::attrEnumName(const std::string& object, const std::string& attr) const {
    Handle obj;
    Handle a = openAttr(*this, object, attr, obj);
    Handle type(H5Aget_type(a.id()));
    if (H5Tget_class(type.id()) == H5T_STRING) return attrString(object, attr);
    if (H5Tget_class(type.id()) != H5T_ENUM) throw IoError(where(object) + ": attribute '" + attr + "' is not an enum");
    Handle mem(H5Tget_native_type(type.id(), H5T_DIR_ASCEND));
    unsigned char raw[8] = {0};
    if (H5Tget_size(type.id()) > sizeof raw || H5Aread(a.id(), mem.id(), raw) < 0)
        throw IoError(where(object) + ": cannot read attribute " + attr);
    char name[256] = {0};
    if (H5Tenum_nameof(mem.id(), raw, name, sizeof name) < 0)
        throw IoError(where(object) + ": attribute " + attr + ": value is not a member of its enum");
    return name;
}

std::vector<double> File::attrDoubles(const std::string& object, const std::string& attr) const {
    Handle obj;
    Handle a = openAttr(*this, object, attr, obj);
    Handle space(H5Aget_space(a.id()));
    const hssize_t n = H5Sget_simple_extent_npoints(space.id());
    std::vector<double> v(elementsToRead({static_cast<hsize_t>(std::max<hssize_t>(n, 0))}, sizeof(double),
                                         where(object) + ": attribute " + attr));
    if (!v.empty() && H5Aread(a.id(), H5T_NATIVE_DOUBLE, v.data()) < 0)
        throw IoError(where(object) + ": cannot read attribute " + attr);
    return v;
}

std::vector<std::string> File::list(const std::string& group) const {
    requireObject(group);
    Handle g(H5Gopen2(id(), group.c_str(), H5P_DEFAULT));
    if (!g.valid()) throw IoError(where(group) + ": not a group");
    H5G_info_t info;
    H5Gget_info(g.id(), &info);
    std::vector<std::string> names;
    for (hsize_t i = 0; i < info.nlinks; ++i) {
        const ssize_t len = H5Lget_name_by_idx(g.id(), ".", H5_INDEX_NAME, H5_ITER_INC, i, nullptr, 0, H5P_DEFAULT);
        std::string name(static_cast<std::size_t>(len), '\0');
        H5Lget_name_by_idx(g.id(), ".", H5_INDEX_NAME, H5_ITER_INC, i, name.data(), name.size() + 1, H5P_DEFAULT);
        names.push_back(name);
    }
    return names;
}

namespace {

/// A coordinate variable beside the grid `gridName`: a 1-D dataset that is an HDF5 dimension
/// scale named `base` (x_m, y_m, month, plane) with its units and long_name. One of that name
/// with the same values (another grid of the same geometry in the group) is shared; otherwise
/// the grid gets its own, named <grid>_<base>. Returns the dataset's path.
template <typename T>
std::string coordinateScale(File& f, const std::string& gridName, const std::string& base, const std::vector<T>& values,
                            const std::string& units, const std::string& longName) {
    const std::string parent = parentOf(gridName);
    const std::string prefix = parent == "/" ? "/" : parent + "/";
    const std::string leaf = gridName.substr(gridName.find_last_of('/') + 1);
    for (const std::string& name : {prefix + base, prefix + leaf + "_" + base}) {
        if (!f.exists(name)) {
            if constexpr (std::is_same_v<T, double>) f.writeF64(name, values, {values.size()}, units);
            else f.writeI32(name, values, {values.size()}, units);
            f.setAttr(name, "long_name", longName);
            Handle ds(H5Dopen2(f.id(), name.c_str(), H5P_DEFAULT));
            if (!ds.valid() || H5DSset_scale(ds.id(), base.c_str()) < 0)
                throw IoError(f.path() + ": " + name + ": cannot make it a dimension scale");
            return name;
        }
        if (f.isGroup(name)) continue;
        Handle ds(H5Dopen2(f.id(), name.c_str(), H5P_DEFAULT));
        if (!ds.valid() || H5DSis_scale(ds.id()) <= 0) continue;
        std::vector<T> existing;
        if constexpr (std::is_same_v<T, double>) {
            if (!f.isIntegerDataset(name)) existing = f.readF64(name);
        } else if (f.isIntegerDataset(name)) {
            existing = f.readI32(name);
        }
        if (existing == values) return name;
    }
    throw IoError(f.path() + ": " + gridName + ": no free name for its coordinate " + base);
}

void attachScale(File& f, const std::string& gridName, const std::string& scaleName, unsigned dim, const char* label) {
    Handle grid(H5Dopen2(f.id(), gridName.c_str(), H5P_DEFAULT));
    Handle scale(H5Dopen2(f.id(), scaleName.c_str(), H5P_DEFAULT));
    if (!grid.valid() || !scale.valid() || H5DSattach_scale(grid.id(), scale.id(), dim) < 0 ||
        H5DSset_label(grid.id(), dim, label) < 0)
        throw IoError(f.path() + ": " + gridName + ": cannot attach the dimension scale " + scaleName);
}

/// The geometry attributes of a grid and its coordinate variables as dimension scales: x_m
/// (last axis) and y_m (the one before) at the cell centres in world metres and, for a stack
/// of `planes` > 0, month 1..12 (12 planes) or plane 0..n-1 on the first axis.
template <typename T>
void writeGeometry(File& f, const std::string& name, const Grid<T>& g, std::size_t planes = 0) {
    const int w = g.width(), h = g.height();
    const double cell = g.cellSizeM(), ox = g.originX(), oy = g.originY();
    f.setAttr(name, "cell_size_m", cell);
    f.setAttr(name, "origin_x_m", ox);
    f.setAttr(name, "origin_y_m", oy);
    f.setAttr(name, "width", static_cast<std::int64_t>(w));
    f.setAttr(name, "height", static_cast<std::int64_t>(h));
    f.setAttr(name, "row_order", std::string("south_to_north"));
    if (!g.crsWkt().empty()) f.setAttr(name, "crs_wkt", g.crsWkt());
    std::vector<double> xs(static_cast<std::size_t>(w)), ys(static_cast<std::size_t>(h));
    for (int ix = 0; ix < w; ++ix) xs[static_cast<std::size_t>(ix)] = ox + (ix + 0.5) * cell;
    for (int iy = 0; iy < h; ++iy) ys[static_cast<std::size_t>(iy)] = oy + (iy + 0.5) * cell;
    const unsigned rank = planes > 0 ? 3 : 2;
    attachScale(f, name, coordinateScale(f, name, "x_m", xs, "m", "x of the cell centres (east), world coordinates"),
                rank - 1, "x");
    attachScale(f, name, coordinateScale(f, name, "y_m", ys, "m", "y of the cell centres (north), world coordinates"),
                rank - 2, "y");
    if (planes == 12) {
        std::vector<std::int32_t> months(12);
        for (int m = 0; m < 12; ++m) months[static_cast<std::size_t>(m)] = m + 1;
        attachScale(f, name, coordinateScale(f, name, "month", months, "1", "month of the year (1 = January)"), 0, "month");
    } else if (planes > 0) {
        std::vector<std::int32_t> index(planes);
        for (std::size_t p = 0; p < planes; ++p) index[p] = static_cast<std::int32_t>(p);
        attachScale(f, name, coordinateScale(f, name, "plane", index, "1", "plane index"), 0, "plane");
    }
}

struct Geometry {
    double cell, ox, oy;
    std::string crsWkt;
};

Geometry readGeometry(const File& f, const std::string& name) {
    Geometry g{f.attrDouble(name, "cell_size_m"), f.attrDouble(name, "origin_x_m"),
               f.attrDouble(name, "origin_y_m"), f.hasAttr(name, "crs_wkt") ? f.attrString(name, "crs_wkt") : std::string()};
    if (!cellSizeInRange(g.cell))
        throw IoError(f.path() + ": " + name + ": cell_size_m " + formatNumber(g.cell, 6) + " " + cellSizeRangeText());
    if (f.hasAttr(name, "row_order") && f.attrString(name, "row_order") != "south_to_north")
        throw IoError(f.path() + ": " + name + ": unsupported row_order '" +
                      f.attrString(name, "row_order") + "'");
    return g;
}

}  // namespace

void File::writeGrid(const std::string& name, const Grid<float>& g, const std::string& units) {
    writeF32(name, g.data(), {static_cast<hsize_t>(g.height()), static_cast<hsize_t>(g.width())}, units);
    writeGeometry(*this, name, g);
}

Grid<float> File::readGrid(const std::string& name) const {
    std::vector<hsize_t> dims;
    auto data = readF32(name, &dims);
    if (dims.size() != 2) throw IoError(where(name) + ": expected a 2-D grid dataset");
    const Geometry geo = readGeometry(*this, name);
    Grid<float> g(static_cast<int>(dims[1]), static_cast<int>(dims[0]), geo.cell, geo.ox, geo.oy);
    g.setCrsWkt(geo.crsWkt);
    g.data() = std::move(data);
    return g;
}

void File::writeGridI32(const std::string& name, const Grid<std::int32_t>& g, const std::string& units) {
    writeI32(name, g.data(), {static_cast<hsize_t>(g.height()), static_cast<hsize_t>(g.width())}, units);
    writeGeometry(*this, name, g);
}

Grid<std::int32_t> File::readGridI32(const std::string& name) const {
    std::vector<hsize_t> dims;
    auto data = readI32(name, &dims);
    if (dims.size() != 2) throw IoError(where(name) + ": expected a 2-D grid dataset");
    const Geometry geo = readGeometry(*this, name);
    Grid<std::int32_t> g(static_cast<int>(dims[1]), static_cast<int>(dims[0]), geo.cell, geo.ox, geo.oy);
    g.setCrsWkt(geo.crsWkt);
    g.data() = std::move(data);
    return g;
}

void File::writeStack(const std::string& name, const std::vector<Grid<float>>& planes,
                      const std::string& units) {
    if (planes.empty()) throw ValidationError(where(name) + ": no planes to write");
    const auto& g0 = planes.front();
    std::vector<float> all;
    all.reserve(g0.size() * planes.size());
    for (const auto& p : planes) {
        if (!p.sameGeometry(g0)) throw ValidationError(where(name) + ": planes differ in geometry");
        all.insert(all.end(), p.data().begin(), p.data().end());
    }
    writeF32(name, all, {static_cast<hsize_t>(planes.size()), static_cast<hsize_t>(g0.height()),
                         static_cast<hsize_t>(g0.width())}, units);
    writeGeometry(*this, name, g0, planes.size());
}

std::vector<Grid<float>> File::readStack(const std::string& name) const {
    std::vector<hsize_t> dims;
    auto data = readF32(name, &dims);
    if (dims.size() != 3) throw IoError(where(name) + ": expected a 3-D [plane][row][column] dataset");
    const Geometry geo = readGeometry(*this, name);
    const std::size_t planeSize = static_cast<std::size_t>(dims[1] * dims[2]);
    std::vector<Grid<float>> out;
    for (hsize_t p = 0; p < dims[0]; ++p) {
        Grid<float> g(static_cast<int>(dims[2]), static_cast<int>(dims[1]), geo.cell, geo.ox, geo.oy);
        g.setCrsWkt(geo.crsWkt);
        std::copy(data.begin() + static_cast<std::ptrdiff_t>(p * planeSize),
                  data.begin() + static_cast<std::ptrdiff_t>((p + 1) * planeSize), g.data().begin());
        out.push_back(std::move(g));
    }
    return out;
}

}  // namespace eco::h5
