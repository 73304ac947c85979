// Comparing two HDF5 outputs in the tests: every group, dataset and attribute, by value.
//
// With `eco --no-provenance` (issue 26 item 7) the same run writes the same bytes, and the
// kill tests run eco so: kCompareOutputBytes compares the files byte for byte. With false,
// the contents are compared without the attributes that record how a run went rather than
// what it computed (isProvenanceAttribute), for outputs written with provenance.
#pragma once

#include <hdf5.h>

#include <cstring>
#include <fstream>
#include <iterator>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <vector>

namespace eco::test {

/// false: compare contents without provenance attributes; true: compare bytes.
constexpr bool kCompareOutputBytes = true;

/// Whether an attribute (or dataset) describes the process rather than the result: wall times (names
/// starting with "wall_" or containing "seconds": seconds, sampling_seconds, ...), thread
/// counts, the year a run was resumed from, the creation time.
inline bool isProvenanceAttribute(const std::string& name) {
    static const std::set<std::string> names = {"threads", "resumed_from_year", "created_utc"};
    return names.count(name) > 0 || name.rfind("wall_", 0) == 0 || name.find("seconds") != std::string::npos;
}

namespace detail {

/// The value of an entry that could not be read: counted as a difference.
constexpr const char* kUnreadable = "(unreadable)";

/// The value of a dataset or attribute as bytes, prefixed by its type class, size and shape.
/// Variable-length strings are read as strings (their pointers mean nothing).
template <typename ReadFn>
std::string valueBytes(hid_t fileType, hid_t space, ReadFn read) {
    const int rank = H5Sget_simple_extent_ndims(space);
    std::vector<hsize_t> dims(static_cast<std::size_t>(rank > 0 ? rank : 0));
    if (rank > 0) H5Sget_simple_extent_dims(space, dims.data(), nullptr);
    const hssize_t n = H5Sget_simple_extent_npoints(space);
    std::ostringstream head;
    head << "class " << H5Tget_class(fileType) << " size " << H5Tget_size(fileType) << " shape";
    for (hsize_t d : dims) head << " " << d;
    head << ":";
    std::string out = head.str();
    if (n <= 0) return out;
    if (H5Tget_class(fileType) == H5T_STRING && H5Tis_variable_str(fileType) > 0) {
        const hid_t mem = H5Tcopy(fileType);  // the file's character set: HDF5 converts none to another
        std::vector<char*> strings(static_cast<std::size_t>(n), nullptr);
        if (read(mem, strings.data()) >= 0) {
            for (char* s : strings) {
                out += s ? s : "(null)";
                out += '\0';
            }
            H5Dvlen_reclaim(mem, space, H5P_DEFAULT, strings.data());
        } else {
            out += kUnreadable;
        }
        H5Tclose(mem);
        return out;
    }
    const hid_t mem = H5Tget_class(fileType) == H5T_STRING ? H5Tcopy(fileType) : H5Tget_native_type(fileType, H5T_DIR_ASCEND);
    std::string bytes(static_cast<std::size_t>(n) * H5Tget_size(mem), '\0');
    if (read(mem, bytes.data()) < 0) bytes = kUnreadable;
    H5Tclose(mem);
    return out + bytes;
}

struct Walk {
    hid_t file = -1;
    std::map<std::string, std::string>* entries = nullptr;
};

inline herr_t collectAttribute(hid_t object, const char* name, const H5A_info_t*, void* data) {
    auto& w = *static_cast<std::pair<std::string, std::map<std::string, std::string>*>*>(data);
    const hid_t attr = H5Aopen(object, name, H5P_DEFAULT);
    const hid_t type = H5Aget_type(attr), space = H5Aget_space(attr);
    (*w.second)[w.first + "@" + name] = valueBytes(type, space, [&](hid_t mem, void* buf) { return H5Aread(attr, mem, buf); });
    H5Sclose(space);
    H5Tclose(type);
    H5Aclose(attr);
    return 0;
}

inline void collectObject(hid_t file, const std::string& path, std::map<std::string, std::string>& entries) {
    const hid_t obj = H5Oopen(file, path.c_str(), H5P_DEFAULT);
    if (obj < 0) {
        entries[path] = detail::kUnreadable;
        return;
    }
    if (H5Iget_type(obj) == H5I_DATASET) {
        const hid_t type = H5Dget_type(obj), space = H5Dget_space(obj);
        entries[path] = valueBytes(type, space, [&](hid_t mem, void* buf) {
            return H5Dread(obj, mem, H5S_ALL, H5S_ALL, H5P_DEFAULT, buf);
        });
        H5Sclose(space);
        H5Tclose(type);
    } else {
        entries[path] = "(group)";
    }
    std::pair<std::string, std::map<std::string, std::string>*> data{path, &entries};
    hsize_t index = 0;
    H5Aiterate2(obj, H5_INDEX_NAME, H5_ITER_INC, &index, collectAttribute, &data);
    H5Oclose(obj);
}

inline herr_t collectLink(hid_t, const char* name, const H5L_info_t*, void* data) {
    auto& w = *static_cast<Walk*>(data);
    collectObject(w.file, std::string("/") + name, *w.entries);
    return 0;
}

}  // namespace detail

/// Every object ("/path") and attribute ("/path@name") of an HDF5 file with its value;
/// {"(unreadable file)": path} when the file cannot be opened.
inline std::map<std::string, std::string> h5Contents(const std::string& path) {
    std::map<std::string, std::string> entries;
    const hid_t file = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
    if (file < 0) return {{path, detail::kUnreadable}};
    detail::collectObject(file, "/", entries);
    detail::Walk w{file, &entries};
    H5Lvisit(file, H5_INDEX_NAME, H5_ITER_INC, detail::collectLink, &w);
    H5Fclose(file);
    return entries;
}

inline std::string fileBytes(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

/// How two HDF5 outputs differ (empty: the same). With kCompareOutputBytes, byte for byte;
/// else entry by entry without the provenance attributes, naming each entry that differs.
inline std::vector<std::string> outputFileDifferences(const std::string& a, const std::string& b) {
    if (kCompareOutputBytes) {
        if (fileBytes(a) == fileBytes(b)) return {};
        return {a + " and " + b + " differ in their bytes"};
    }
    // An attribute by its name, a dataset by its last path component (/iterations/seconds).
    auto isProvenance = [](const std::string& key) {
        const std::size_t at = key.find('@');
        return isProvenanceAttribute(at != std::string::npos ? key.substr(at + 1) : key.substr(key.rfind('/') + 1));
    };
    const auto ea = h5Contents(a), eb = h5Contents(b);
    std::vector<std::string> diffs;
    for (const auto& [key, value] : ea) {
        if (isProvenance(key)) continue;
        if (value.find(detail::kUnreadable) != std::string::npos) diffs.push_back(key + ": cannot be read");
        const auto it = eb.find(key);
        if (it == eb.end()) diffs.push_back(key + ": only in " + a);
        else if (it->second != value) diffs.push_back(key + ": differs");
    }
    for (const auto& [key, value] : eb)
        if (!isProvenance(key) && !ea.count(key)) diffs.push_back(key + ": only in " + b);
    return diffs;
}

}  // namespace eco::test
