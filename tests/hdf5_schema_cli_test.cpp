// HDF5 that explains itself (issue 31 item 1, docs/hdf5.md): every kind of file eco writes is
// made by one small `eco run` and walked object by object with the HDF5 C API, independently
// of core/h5io's readers, against the rules docs/hdf5.md states for every file:
// * root `format` (one of the kinds the document's table lists), `schema_version` (an
//   integer), `code_version`;
// * a `units` attribute on every numeric dataset ("1" when dimensionless, CF's convention);
// * every grid (a float dataset with `cell_size_m`) has dimension scales attached to its
//   axes: x_m and y_m at the cell centres in world metres, month 1..12 on a monthly stack;
// * typed attributes: no number or boolean written as text, seeds as integers, choices as
//   HDF5 enums, ids as integer datasets;
// * /provenance (when recorded) with the code version, git commit, command line and the
//   input files with their hashes.
#include <catch2/catch.hpp>
#include <hdf5.h>
#include <hdf5_hl.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "test_util.h"

namespace {

/// Closes an HDF5 identifier of any kind.
struct Id {
    hid_t id;
    explicit Id(hid_t i) : id(i) {}
    Id(const Id&) = delete;
    Id& operator=(const Id&) = delete;
    ~Id() {
        if (id < 0) return;
        switch (H5Iget_type(id)) {
            case H5I_FILE: H5Fclose(id); break;
            case H5I_GROUP: H5Gclose(id); break;
            case H5I_DATASET: H5Dclose(id); break;
            case H5I_DATASPACE: H5Sclose(id); break;
            case H5I_DATATYPE: H5Tclose(id); break;
            case H5I_ATTR: H5Aclose(id); break;
            default: break;
        }
    }
};

/// The kinds of file docs/hdf5.md lists in its table "The files" (`format` column).
std::set<std::string> documentedFormats() {
    std::ifstream in(eco::test::sourcePath("docs/hdf5.md"));
    std::string line;
    std::set<std::string> out;
    const std::regex row(R"(^\| `(eco-[a-z0-9-]+)`)");
    std::smatch m;
    while (std::getline(in, line))
        if (std::regex_search(line, m, row)) out.insert(m[1]);
    return out;
}

std::string readStringAttr(hid_t attr) {
    Id type(H5Aget_type(attr));
    if (H5Tis_variable_str(type.id) > 0) {
        Id space(H5Aget_space(attr));
        std::vector<char*> p(static_cast<std::size_t>(std::max<hssize_t>(1, H5Sget_simple_extent_npoints(space.id))), nullptr);
        Id mem(H5Tcopy(H5T_C_S1));
        H5Tset_size(mem.id, H5T_VARIABLE);
        H5Aread(attr, mem.id, p.data());
        std::string s = p[0] ? p[0] : "";
        for (char* q : p) H5free_memory(q);
        return s;
    }
    // Fixed-length: every element (an array attribute holds several), the first one returned.
    Id space(H5Aget_space(attr));
    const std::size_t width = H5Tget_size(type.id);
    const auto n = static_cast<std::size_t>(std::max<hssize_t>(1, H5Sget_simple_extent_npoints(space.id)));
    std::string s(width * n, '\0');
    H5Aread(attr, type.id, s.data());
    s.resize(width);
    return s.substr(0, s.find('\0'));
}

/// A text value that should have been written as a number or a boolean.
bool looksTyped(const std::string& s) {
    if (s == "true" || s == "false") return true;
    if (s.empty()) return false;
    char* end = nullptr;
    std::strtod(s.c_str(), &end);
    return end == s.c_str() + s.size();
}

/// Attributes whose values are choices among names: HDF5 enums.
const std::set<std::string> kEnumAttributes = {"growth_rule", "competition", "germination_cells", "germination_vigour",
                                               "canopy_limit", "refined", "undergrowth_shades"};

struct Walk {
    std::string file;
    std::vector<std::string> problems;
    int grids = 0, monthlyGrids = 0, datasets = 0;
    void problem(const std::string& object, const std::string& what) { problems.push_back(file + ": " + object + ": " + what); }
};

void checkAttributes(hid_t obj, const std::string& name, Walk& w) {
    H5O_info_t info;
    H5Oget_info(obj, &info);
    for (hsize_t i = 0; i < info.num_attrs; ++i) {
        Id a(H5Aopen_by_idx(obj, ".", H5_INDEX_NAME, H5_ITER_INC, i, H5P_DEFAULT, H5P_DEFAULT));
        const ssize_t len = H5Aget_name(a.id, 0, nullptr);
        std::string an(static_cast<std::size_t>(len), '\0');
        H5Aget_name(a.id, an.size() + 1, an.data());
        Id type(H5Aget_type(a.id));
        const H5T_class_t cls = H5Tget_class(type.id);
        if (cls == H5T_STRING) {
            const std::string v = readStringAttr(a.id);
            // Units ("1" is CF's dimensionless unit); hashes and commits are hex digits, which may
            // happen to read as a number.
            static const std::set<std::string> kText = {"units", "git_commit", "input_fnv1a64", "fingerprint"};
            if (!kText.count(an) && looksTyped(v)) w.problem(name, "attribute " + an + " = '" + v + "' is a number or boolean written as text");
        }
        const bool seed = an == "seed" || (an.size() > 5 && an.compare(an.size() - 5, 5, "_seed") == 0);
        if (seed && cls != H5T_INTEGER)
            w.problem(name, "attribute " + an + " (a seed) is not an integer");
        if (kEnumAttributes.count(an) && cls != H5T_ENUM) w.problem(name, "attribute " + an + " (a choice) is not an HDF5 enum");
    }
}

/// Values of a 1-D numeric dataset as doubles.
std::vector<double> readDoubles(hid_t ds) {
    Id space(H5Dget_space(ds));
    std::vector<double> v(static_cast<std::size_t>(H5Sget_simple_extent_npoints(space.id)));
    if (!v.empty()) H5Dread(ds, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, v.data());
    return v;
}

double doubleAttr(hid_t obj, const char* name) {
    double v = std::nan("");
    if (H5Aexists(obj, name) > 0) {
        Id a(H5Aopen(obj, name, H5P_DEFAULT));
        H5Aread(a.id, H5T_NATIVE_DOUBLE, &v);
    }
    return v;
}

/// The values of the one scale attached to dimension `dim` of `ds`, and its name.
bool attachedScale(hid_t ds, unsigned dim, std::vector<double>& values, std::string& scaleName) {
    if (H5DSget_num_scales(ds, dim) != 1) return false;
    struct Out {
        std::vector<double>* values;
        std::string* name;
    } out{&values, &scaleName};
    int idx = 0;
    const herr_t r = H5DSiterate_scales(
        ds, dim, &idx,
        [](hid_t, unsigned, hid_t scale, void* data) -> herr_t {
            auto* o = static_cast<Out*>(data);
            *o->values = readDoubles(scale);
            char buf[256] = {0};
            H5DSget_scale_name(scale, buf, sizeof buf);
            *o->name = buf;
            return 1;
        },
        &out);
    return r >= 0;
}

void checkGrid(hid_t ds, const std::string& name, int rank, const std::vector<hsize_t>& dims, Walk& w) {
    ++w.grids;
    const double cell = doubleAttr(ds, "cell_size_m"), ox = doubleAttr(ds, "origin_x_m"), oy = doubleAttr(ds, "origin_y_m");
    const auto checkAxis = [&](unsigned dim, const std::string& expectName, double origin) {
        std::vector<double> v;
        std::string scale;
        if (!attachedScale(ds, dim, v, scale)) {
            w.problem(name, "no dimension scale attached to dimension " + std::to_string(dim) + " (" + expectName + ")");
            return;
        }
        if (scale.rfind(expectName, 0) != 0) w.problem(name, "dimension " + std::to_string(dim) + " has scale '" + scale + "', expected " + expectName);
        if (v.size() != dims[dim]) {
            w.problem(name, "scale " + expectName + " has " + std::to_string(v.size()) + " values for " + std::to_string(dims[dim]) + " cells");
            return;
        }
        for (std::size_t i = 0; i < v.size(); ++i) {
            const double centre = origin + (static_cast<double>(i) + 0.5) * cell;
            if (std::abs(v[i] - centre) > 1e-9 * std::max(1.0, std::abs(centre))) {
                w.problem(name, "scale " + expectName + "[" + std::to_string(i) + "] = " + std::to_string(v[i]) +
                                    ", not the cell centre " + std::to_string(centre));
                return;
            }
        }
    };
    checkAxis(static_cast<unsigned>(rank - 1), "x_m", ox);
    checkAxis(static_cast<unsigned>(rank - 2), "y_m", oy);
    if (rank == 3 && dims[0] == 12) {
        ++w.monthlyGrids;
        std::vector<double> v;
        std::string scale;
        if (!attachedScale(ds, 0, v, scale) || scale.rfind("month", 0) != 0 || v.size() != 12 || v.front() != 1 || v.back() != 12)
            w.problem(name, "a monthly stack without the month scale 1..12 on dimension 0");
    }
}

herr_t visitObject(hid_t root, const char* rawName, const H5O_info_t* info, void* data) {
    auto& w = *static_cast<Walk*>(data);
    const std::string name = std::string("/") + (std::string(rawName) == "." ? "" : rawName);
    Id obj(H5Oopen(root, rawName, H5P_DEFAULT));
    checkAttributes(obj.id, name, w);
    if (info->type != H5O_TYPE_DATASET) return 0;
    ++w.datasets;
    Id type(H5Dget_type(obj.id));
    const H5T_class_t cls = H5Tget_class(type.id);
    const std::string leaf = name.substr(name.find_last_of('/') + 1);
    if (cls == H5T_STRING) return 0;  // lists of names carry no units (CF: units are for numbers)
    if (H5Aexists(obj.id, "units") <= 0) w.problem(name, "numeric dataset without a units attribute");
    if ((leaf == "id" || (leaf.size() > 3 && leaf.compare(leaf.size() - 3, 3, "_id") == 0)) && cls != H5T_INTEGER)
        w.problem(name, "an id dataset that is not of an integer type");
    Id space(H5Dget_space(obj.id));
    const int rank = H5Sget_simple_extent_ndims(space.id);
    std::vector<hsize_t> dims(static_cast<std::size_t>(std::max(rank, 0)));
    H5Sget_simple_extent_dims(space.id, dims.data(), nullptr);
    if (cls == H5T_FLOAT && (rank == 2 || rank == 3) && H5Aexists(obj.id, "cell_size_m") > 0) checkGrid(obj.id, name, rank, dims, w);
    return 0;
}

void checkRoot(hid_t f, Walk& w, const std::set<std::string>& formats, std::string& format) {
    for (const char* a : {"format", "schema_version", "code_version"})
        if (H5Aexists(f, a) <= 0) w.problem("/", std::string("root attribute ") + a + " missing");
    if (H5Aexists(f, "format") > 0) {
        Id a(H5Aopen(f, "format", H5P_DEFAULT));
        format = readStringAttr(a.id);
        if (!formats.count(format)) w.problem("/", "format '" + format + "' is not in docs/hdf5.md's table of files");
    }
    if (H5Aexists(f, "schema_version") > 0) {
        Id a(H5Aopen(f, "schema_version", H5P_DEFAULT));
        Id t(H5Aget_type(a.id));
        if (H5Tget_class(t.id) != H5T_INTEGER) w.problem("/", "schema_version is not an integer");
    }
}

void checkProvenance(hid_t f, Walk& w) {
    if (H5Lexists(f, "provenance", H5P_DEFAULT) <= 0) {
        w.problem("/provenance", "missing (the run records provenance)");
        return;
    }
    Id g(H5Gopen2(f, "provenance", H5P_DEFAULT));
    for (const char* a : {"code_version", "git_commit", "command_line"}) {
        if (H5Aexists(g.id, a) <= 0) {
            w.problem("/provenance", std::string("attribute ") + a + " missing");
            continue;
        }
        Id attr(H5Aopen(g.id, a, H5P_DEFAULT));
        if (readStringAttr(attr.id).empty()) w.problem("/provenance", std::string("attribute ") + a + " is empty");
    }
}

}  // namespace

TEST_CASE("hdf5 schema: every file eco run writes follows docs/hdf5.md (units, dimension scales, typed attributes, provenance)",
          "[hdf5][schema][cli]") {
    eco::test::TempDir dir("schema");
    const std::string cfg = dir.file("pipeline.toml"), out = dir.file("out");
    // The simulation with disturbance on, so that its event table is walked too
    // (docs/disturbance.md): the default simulation configuration plus a forced fire and storm.
    const std::string simCfg = dir.file("sim.toml");
    {
        std::ifstream in(eco::test::sourcePath("configs/sim-default.toml"));
        std::ofstream f(simCfg);
        f << in.rdbuf() << "\n[disturbance.fire]\nyears = [1]\n[disturbance.storm]\nyears = [0]\n";
    }
    {
        std::ofstream f(cfg);
        f << "[run]\nout_dir = \"" << out << "\"\nseed = 4\n"
          << "[terrain]\nwidth = 48\nheight = 40\ncell_size_m = 0.914\n"
          << "[chm]\n[abiotics]\nsun_step_minutes = 120\n[canopy]\n"
          << "[simulate]\nconfig = \"" << simCfg << "\"\nyears = 2\n"
          << "crop = [4.0, 4.0, 36.0, 32.0]\n"
          << "[analyse]\nkmax = 2\n"
          << "[synth]\ntarget_seed = 9\nwidth = 40\nheight = 40\n";
    }
    const auto r = eco::test::runEco("run " + cfg);
    INFO(r.output);
    REQUIRE(r.exitCode == 0);

    const std::set<std::string> formats = documentedFormats();
    REQUIRE(formats.size() >= 7);
    std::set<std::string> seen;
    std::vector<std::string> problems;
    int grids = 0, monthly = 0, files = 0;
    for (const auto& e : std::filesystem::recursive_directory_iterator(out)) {
        if (e.path().extension() != ".h5") continue;
        ++files;
        Walk w;
        w.file = std::filesystem::relative(e.path(), out).string();
        Id f(H5Fopen(e.path().c_str(), H5F_ACC_RDONLY, H5P_DEFAULT));
        REQUIRE(f.id >= 0);
        std::string format;
        checkRoot(f.id, w, formats, format);
        seen.insert(format);
        checkProvenance(f.id, w);
        H5Ovisit(f.id, H5_INDEX_NAME, H5_ITER_INC, visitObject, &w);
        problems.insert(problems.end(), w.problems.begin(), w.problems.end());
        grids += w.grids;
        monthly += w.monthlyGrids;
        CHECK(w.datasets > 0);
    }
    // At most 40 problems shown: one line each.
    std::ostringstream shown;
    for (std::size_t i = 0; i < problems.size() && i < 40; ++i) shown << problems[i] << "\n";
    INFO(problems.size() << " problems:\n" << shown.str());
    CHECK(problems.empty());
    // Every kind of file: terrain, chm, abiotics, canopy, simulation (and its checkpoint),
    // database, scene.
    for (const char* kind : {"eco-terrain", "eco-chm", "eco-abiotics", "eco-canopy", "eco-simulation", "eco-biome-db", "eco-scene"}) {
        INFO(kind);
        CHECK(seen.count(kind) == 1);
    }
    CHECK(files >= 11);
    CHECK(grids >= 10);
    CHECK(monthly >= 1);
}
