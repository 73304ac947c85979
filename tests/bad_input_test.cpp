// Issue 26, item 2: a corpus of bad inputs, every one made by this test from small valid
// files that the eco binary writes first (a terrain, a CHM, abiotics, a canopy, a
// simulation, a database, a scene). Each case runs one command and asserts
//   * the exit code: 1 for bad data, 2 for a usage error (eco --help, docs/robustness.md);
//   * one message line ("eco: error: ..." or CLI11's "--flag: ...") that contains the
//     fragments naming the file, the field and the value;
//   * no output file left in the case's output folder, and no stray library lines
//     (libpng's own "libpng error:"), no internal error.
// A case that eco accepted, or that it refused with another code or a vaguer message, fails
// with the command line and eco's whole output.
#include <catch2/catch.hpp>

#include <hdf5.h>

#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>
#include <set>
#include <string>
#include <vector>

#include "test_util.h"

namespace fs = std::filesystem;
using eco::test::runEco;
using eco::test::TempDir;

namespace {

using eco::test::writeText;

std::string readText(const std::string& path) {
    std::ifstream f(path, std::ios::binary);
    std::ostringstream s;
    s << f.rdbuf();
    return s.str();
}

std::string replaceAll(std::string s, const std::string& from, const std::string& to) {
    for (std::size_t at = s.find(from); at != std::string::npos; at = s.find(from, at + to.size())) s.replace(at, from.size(), to);
    return s;
}

/// Replace the first occurrence of `from` (which must be there: a fixture that changed
/// would otherwise make a case test nothing).
std::string replaceOnce(const std::string& s, const std::string& from, const std::string& to) {
    const std::size_t at = s.find(from);
    REQUIRE(at != std::string::npos);
    return s.substr(0, at) + to + s.substr(at + from.size());
}

// ------------------------------------------------------------------ HDF5 edits (C API)

struct H5Edit {
    hid_t file;
    explicit H5Edit(const std::string& path) : file(H5Fopen(path.c_str(), H5F_ACC_RDWR, H5P_DEFAULT)) { REQUIRE(file >= 0); }
    ~H5Edit() { H5Fclose(file); }
    H5Edit(const H5Edit&) = delete;
    H5Edit& operator=(const H5Edit&) = delete;

    /// Set element `index` of a dataset (any numeric type, converted from double).
    void setNumber(const std::string& dataset, std::size_t index, double value) {
        const hid_t d = H5Dopen2(file, dataset.c_str(), H5P_DEFAULT);
        REQUIRE(d >= 0);
        const hid_t space = H5Dget_space(d);
        const hssize_t n = H5Sget_simple_extent_npoints(space);
        REQUIRE(static_cast<hssize_t>(index) < n);
        std::vector<double> v(static_cast<std::size_t>(n));
        REQUIRE(H5Dread(d, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, v.data()) >= 0);
        v[index] = value;
        REQUIRE(H5Dwrite(d, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, v.data()) >= 0);
        H5Sclose(space);
        H5Dclose(d);
    }
    /// Replace a dataset by its first `n` elements, as a 1-D float64 array.
    void truncate(const std::string& dataset, std::size_t n) {
        const hid_t d = H5Dopen2(file, dataset.c_str(), H5P_DEFAULT);
        REQUIRE(d >= 0);
        const hid_t space = H5Dget_space(d);
        std::vector<double> v(static_cast<std::size_t>(H5Sget_simple_extent_npoints(space)));
        REQUIRE(H5Dread(d, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, v.data()) >= 0);
        H5Sclose(space);
        H5Dclose(d);
        remove(dataset);
        const hsize_t dims[1] = {n};
        const hid_t s = H5Screate_simple(1, dims, nullptr);
        const hid_t nd = H5Dcreate2(file, dataset.c_str(), H5T_IEEE_F64LE, s, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
        REQUIRE(nd >= 0);
        REQUIRE(H5Dwrite(nd, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, v.data()) >= 0);
        H5Dclose(nd);
        H5Sclose(s);
    }
    void remove(const std::string& object) { REQUIRE(H5Ldelete(file, object.c_str(), H5P_DEFAULT) >= 0); }
    /// Replace (or add) a scalar attribute of `fileType`, written from `value` in `memType`.
    void putScalarAttr(const std::string& object, const std::string& name, hid_t fileType, hid_t memType, const void* value) {
        if (H5Aexists_by_name(file, object.c_str(), name.c_str(), H5P_DEFAULT) > 0)
            H5Adelete_by_name(file, object.c_str(), name.c_str(), H5P_DEFAULT);
        const hid_t s = H5Screate(H5S_SCALAR);
        const hid_t a = H5Acreate_by_name(file, object.c_str(), name.c_str(), fileType, s, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
        REQUIRE(a >= 0);
        H5Awrite(a, memType, value);
        H5Aclose(a);
        H5Sclose(s);
    }
    void setAttr(const std::string& object, const std::string& name, double value) {
        putScalarAttr(object, name, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, &value);
    }
    void setAttrInt(const std::string& object, const std::string& name, long long value) {
        putScalarAttr(object, name, H5T_STD_I64LE, H5T_NATIVE_LLONG, &value);
    }
    void setAttrText(const std::string& object, const std::string& name, const std::string& value) {
        const hid_t t = H5Tcopy(H5T_C_S1);
        H5Tset_size(t, value.size() + 1);
        putScalarAttr(object, name, t, t, value.c_str());
        H5Tclose(t);
    }
};

// ------------------------------------------------------------------ the valid inputs

/// Small valid inputs written once per test process by the eco binary itself.
struct GoodInputs {
    TempDir dir{"bad_input_good"};
    std::string terrainH5, terrainAsc, terrainPng, chm, abiotics, canopy, sim, db, scene, points, biome, simConfig;

    GoodInputs() {
        terrainH5 = dir.file("t.h5");
        terrainAsc = dir.file("t.asc");
        terrainPng = dir.file("t.png");
        chm = dir.file("chm.h5");
        abiotics = dir.file("ab.h5");
        canopy = dir.file("can.h5");
        sim = dir.file("sim.h5");
        db = dir.file("db.h5");
        scene = dir.file("scene.h5");
        points = dir.file("points.csv");
        biome = eco::test::sourcePath("biomes/sonoma.toml");
        simConfig = eco::test::sourcePath("configs/sim-default.toml");
        const std::string grid = " --width 48 --height 48 --cell-size 1 --seed 3";
        for (const std::string& args :
             {"terrain generate --out " + terrainH5 + grid, "terrain generate --out " + terrainAsc + grid,
              "terrain generate --out " + terrainPng + grid,
              "chm generate --terrain " + terrainH5 + " --out " + chm + " --dense-spacing 6 --sparse-spacing 10",
              "abiotics --terrain " + terrainH5 + " --out " + abiotics + " --sun-step 60",
              "canopy --terrain " + terrainH5 + " --chm " + chm + " --abiotics " + abiotics + " --out " + canopy,
              "simulate --abiotics " + abiotics + " --canopy " + canopy + " --years 3 --out " + sim,
              "analyse " + sim + " --out " + db + " --rmax 4 --kmax 2",
              "synth --terrain " + terrainH5 + " --canopy " + canopy + " --database " + db + " --abiotics " + abiotics +
                  " --out " + scene}) {
            const auto r = runEco(args);
            INFO("eco " << args << "\n" << r.output);
            REQUIRE(r.exitCode == 0);
        }
        writeText(points, "x,y\n1,2\n3,4\n5,5\n6,1\n");
    }
};

const GoodInputs& good() {
    static const GoodInputs g;
    return g;
}

// ------------------------------------------------------------------ the corpus

struct CaseDirs {
    std::string in;   ///< where the case writes its bad files
    std::string out;  ///< where the command is told to write (must stay empty)
    std::string file(const std::string& name) const { return in + "/" + name; }
};

struct BadCase {
    std::string name;
    std::function<void(const GoodInputs&, const CaseDirs&)> make;  ///< writes the bad inputs (may be empty)
    std::string args;  ///< {T} {A} {C} {S} {D} {SC} {P} {TA} {TP} {CHM} {BI} {SIMCFG}: the good inputs; {I}/x: a bad one; {O}: output folder
    int exitCode;
    std::vector<std::string> fragments;  ///< all in the message line
};

std::string expand(std::string args, const GoodInputs& g, const CaseDirs& d) {
    const std::pair<const char*, std::string> keys[] = {
        {"{SIMCFG}", g.simConfig}, {"{CHM}", g.chm}, {"{BI}", g.biome}, {"{TA}", g.terrainAsc}, {"{TP}", g.terrainPng},
        {"{SC}", g.scene},         {"{T}", g.terrainH5}, {"{A}", g.abiotics}, {"{C}", g.canopy}, {"{S}", g.sim},
        {"{D}", g.db},             {"{P}", g.points},   {"{I}", d.in},        {"{O}", d.out}};
    for (const auto& [key, value] : keys) args = replaceAll(args, key, value);
    return args;
}

/// Copy a good file into the case's folder and edit it there.
std::string copyEdit(const std::string& from, const CaseDirs& d, const std::string& name,
                     const std::function<void(H5Edit&)>& edit) {
    const std::string to = d.file(name);
    fs::copy_file(from, to, fs::copy_options::overwrite_existing);
    H5Edit e(to);
    edit(e);
    return to;
}

std::function<void(const GoodInputs&, const CaseDirs&)> h5Case(const std::string GoodInputs::*file, const std::string& name,
                                                                std::function<void(H5Edit&)> edit) {
    return [file, name, edit](const GoodInputs& g, const CaseDirs& d) { copyEdit(g.*file, d, name, edit); };
}

std::function<void(const GoodInputs&, const CaseDirs&)> textCase(const std::string& name, std::string text) {
    return [name, text](const GoodInputs&, const CaseDirs& d) { writeText(d.file(name), text); };
}

/// A biome TOML: the repository's Sonoma biome with `from` replaced by `to` once.
std::function<void(const GoodInputs&, const CaseDirs&)> biomeCase(std::string from, std::string to) {
    return [from, to](const GoodInputs& g, const CaseDirs& d) { writeText(d.file("b.toml"), replaceOnce(readText(g.biome), from, to)); };
}

std::string ascHeader(const std::string& ncols, const std::string& nrows, const std::string& cell) {
    return "ncols " + ncols + "\nnrows " + nrows + "\nxllcorner 0\nyllcorner 0\ncellsize " + cell + "\n";
}
const std::string kRows = "1 2 3 4\n1 2 3 4\n1 2 3 4\n";

/// A simulation configuration on the good inputs, with `extra` appended to its tables.
std::function<void(const GoodInputs&, const CaseDirs&)> simConfigCase(std::string runExtra, std::string modelExtra) {
    return [runExtra, modelExtra](const GoodInputs& g, const CaseDirs& d) {
        writeText(d.file("sim.toml"), "[inputs]\nabiotics = \"" + g.abiotics + "\"\ncanopy = \"" + g.canopy +
                                          "\"\n[run]\nyears = 2\n" + runExtra + "\n[outputs]\nhdf5 = \"" + d.out +
                                          "/s.h5\"\n[model]\n" + modelExtra + "\n");
    };
}

/// A pipeline configuration (eco run) on a small generated terrain, edited by `edit`.
std::function<void(const GoodInputs&, const CaseDirs&)> runConfigCase(std::function<std::string(std::string)> edit) {
    return [edit](const GoodInputs& g, const CaseDirs& d) {
        const std::string base = "[run]\nout_dir = \"" + d.out + "/run\"\nseed = 1\n[terrain]\nwidth = 48\nheight = 48\n"
                                 "cell_size_m = 1.0\n[chm]\n[abiotics]\n[canopy]\n[simulate]\nconfig = \"" + g.simConfig +
                                 "\"\nyears = 2\ncrop = [0.0, 0.0, 40.0, 40.0]\n[analyse]\n[synth]\ntarget_seed = 2\n";
        writeText(d.file("run.toml"), edit(base));
    };
}

using G = GoodInputs;

std::vector<BadCase> corpus() {
    const std::string synth = "synth --terrain {T} --canopy {C} --database {D} --abiotics {A} --out {O}/s.h5";
    const std::string simulate = "simulate --abiotics {A} --canopy {C} --years 1 --out {O}/s.h5";
    const std::string canopy = "canopy --terrain {T} --chm {CHM} --abiotics {A} --out {O}/c.h5";
    const double nan = std::nan("");
    const double inf = HUGE_VAL;
    std::vector<BadCase> c;
    auto add = [&](BadCase b) { c.push_back(std::move(b)); };

    // ---- biome databases (eco synth, eco inspect, eco compare)
    add({"db negative density", h5Case(&G::db, "db.h5", [](H5Edit& e) { e.setNumber("/regions/density_per_m2", 0, -1); }),
         "synth --terrain {T} --canopy {C} --database {I}/db.h5 --abiotics {A} --out {O}/s.h5", 1,
         {"db.h5", "/regions/density_per_m2", "entry 0 is -1"}});
    add({"db NaN density", h5Case(&G::db, "db.h5", [=](H5Edit& e) { e.setNumber("/regions/density_per_m2", 0, nan); }),
         "inspect {I}/db.h5", 1, {"db.h5", "/regions/density_per_m2", "nan"}});
    add({"db missing dataset", h5Case(&G::db, "db.h5", [](H5Edit& e) { e.remove("/regions/density_per_m2"); }),
         "inspect {I}/db.h5", 1, {"db.h5", "/regions/density_per_m2", "missing"}});
    add({"db wrong format", h5Case(&G::db, "db.h5", [](H5Edit& e) { e.setAttrText("/", "format", "eco-scene"); }),
         "inspect {I}/db.h5", 1, {"db.h5", "not a biome database", "eco-scene"}});
    add({"db future schema", h5Case(&G::db, "db.h5", [](H5Edit& e) { e.setAttrInt("/", "schema_version", 99); }),
         "inspect {I}/db.h5", 1, {"db.h5", "schema_version 99"}});
    add({"db NaN bin edge", h5Case(&G::db, "db.h5", [=](H5Edit& e) { e.setNumber("/bins/pcf_edges_m", 3, nan); }),
         "inspect {I}/db.h5", 1, {"db.h5", "/bins/pcf_edges_m", "edge 3 is nan"}});
    add({"db region of another combination",
         h5Case(&G::db, "db.h5", [](H5Edit& e) { e.setNumber("/regions/combination", 0, 999); }), "inspect {I}/db.h5", 1,
         {"db.h5", "/regions", "region 0 has combination 999"}});
    add({"db region list out of range",
         h5Case(&G::db, "db.h5", [](H5Edit& e) { e.setNumber("/combinations/first_region", 0, 7); }), "inspect {I}/db.h5", 1,
         {"db.h5", "/combinations", "regions 7"}});
    add({"db negative k", h5Case(&G::db, "db.h5", [](H5Edit& e) { e.setNumber("/combinations/k", 0, -3); }),
         "inspect {I}/db.h5", 1, {"db.h5", "/combinations"}});
    add({"db mask 0", h5Case(&G::db, "db.h5", [](H5Edit& e) { e.setNumber("/combinations/mask", 0, 0); }),
         "inspect {I}/db.h5", 1, {"db.h5", "/combinations/mask", "mask 0"}});
    add({"db feature names short", h5Case(&G::db, "db.h5", [](H5Edit& e) { e.remove("/features/names"); }),
         "inspect {I}/db.h5", 1, {"db.h5", "/features/names"}});
    add({"db negative share", h5Case(&G::db, "db.h5", [](H5Edit& e) { e.setNumber("/regions/species_proportion", 0, -0.5); }),
         "inspect {I}/db.h5", 1, {"db.h5", "/regions/species_proportion", "-0.5"}});
    add({"db share above 1", h5Case(&G::db, "db.h5", [](H5Edit& e) { e.setNumber("/regions/species_proportion", 0, 1.5); }),
         "inspect {I}/db.h5", 1, {"db.h5", "/regions/species_proportion", "1.5"}});
    add({"db infinite centroid", h5Case(&G::db, "db.h5", [=](H5Edit& e) { e.setNumber("/regions/centroid_raw", 0, inf); }),
         "inspect {I}/db.h5", 1, {"db.h5", "/regions/centroid_raw", "inf"}});
    add({"db NaN g", h5Case(&G::db, "db.h5", [=](H5Edit& e) { e.setNumber("/regions/region_0000/pairs/g", 0, nan); }),
         "inspect {I}/db.h5", 1, {"db.h5", "/regions/region_0000/pairs/g", "nan"}});
    add({"db negative area", h5Case(&G::db, "db.h5", [](H5Edit& e) { e.setNumber("/regions/area_m2", 0, -4); }),
         "inspect {I}/db.h5", 1, {"db.h5", "/regions/area_m2", "-4"}});
    add({"db zero feature std", h5Case(&G::db, "db.h5", [](H5Edit& e) { e.setNumber("/combinations/feature_std", 0, 0); }),
         "inspect {I}/db.h5", 1, {"db.h5", "/combinations/feature_std"}});
    add({"simulation given as database", nullptr, "inspect {S}", 1, {"sim.h5", "not a biome database", "eco-simulation"}});
    add({"database given as scene", nullptr, "compare {D} {D} --out {O}/c.md", 1, {"db.h5", "not an eco-scene file"}});
    add({"scene given as database", nullptr, "compare {SC} {SC} --out {O}/c.md", 1, {"scene.h5", "not a biome database"}});

    // ---- canopy files
    add({"canopy NaN x", h5Case(&G::canopy, "c.h5", [=](H5Edit& e) { e.setNumber("/canopy/x", 0, nan); }),
         "synth --terrain {T} --canopy {I}/c.h5 --database {D} --abiotics {A} --out {O}/s.h5", 1,
         {"c.h5", "/canopy", "plant 0"}});
    add({"canopy negative radius", h5Case(&G::canopy, "c.h5", [](H5Edit& e) { e.setNumber("/canopy/crown_radius", 0, -2); }),
         "simulate --abiotics {A} --canopy {I}/c.h5 --years 1 --out {O}/s.h5", 1, {"c.h5", "/canopy", "plant 0"}});
    add({"canopy species id out of range", h5Case(&G::canopy, "c.h5", [](H5Edit& e) { e.setNumber("/canopy/species_id", 0, 99); }),
         "simulate --abiotics {A} --canopy {I}/c.h5 --years 1 --out {O}/s.h5", 1, {"c.h5", "/canopy/species_id", "99"}});
    add({"canopy arrays differ in length", h5Case(&G::canopy, "c.h5", [](H5Edit& e) { e.truncate("/canopy/x", 3); }),
         "simulate --abiotics {A} --canopy {I}/c.h5 --years 1 --out {O}/s.h5", 1, {"c.h5", "/canopy", "differ in length"}});
    add({"canopy infinite height", h5Case(&G::canopy, "c.h5", [=](H5Edit& e) { e.setNumber("/canopy/height", 0, inf); }),
         "synth --terrain {T} --canopy {I}/c.h5 --database {D} --abiotics {A} --out {O}/s.h5", 1, {"c.h5", "/canopy"}});
    add({"canopy without CHM", h5Case(&G::canopy, "c.h5", [](H5Edit& e) { e.remove("/chm/height"); }),
         "simulate --abiotics {A} --canopy {I}/c.h5 --years 1 --out {O}/s.h5", 1, {"c.h5", "/chm/height"}});
    add({"canopy NaN CHM cell", h5Case(&G::canopy, "c.h5", [=](H5Edit& e) { e.setNumber("/chm/height", 5, nan); }),
         "simulate --abiotics {A} --canopy {I}/c.h5 --years 1 --out {O}/s.h5", 1, {"c.h5", "/chm/height", "nan", "column 5"}});
    add({"canopy negative CHM cell", h5Case(&G::canopy, "c.h5", [](H5Edit& e) { e.setNumber("/chm/height", 7, -3); }),
         "simulate --abiotics {A} --canopy {I}/c.h5 --years 1 --out {O}/s.h5", 1, {"c.h5", "/chm/height", "-3"}});
    add({"canopy wrong format", h5Case(&G::canopy, "c.h5", [](H5Edit& e) { e.setAttrText("/", "format", "eco-biome-db"); }),
         "simulate --abiotics {A} --canopy {I}/c.h5 --years 1 --out {O}/s.h5", 1, {"c.h5", "not an eco-canopy file"}});
    add({"database given as canopy", nullptr, "simulate --abiotics {A} --canopy {D} --years 1 --out {O}/s.h5", 1,
         {"db.h5", "not an eco-canopy file"}});

    // ---- simulation files (eco analyse)
    add({"simulation wrong format", h5Case(&G::sim, "s.h5", [](H5Edit& e) { e.setAttrText("/", "format", "nope"); }),
         "analyse {I}/s.h5 --out {O}/db.h5", 1, {"s.h5", "not a simulation file", "nope"}});
    add({"simulation without canopy", h5Case(&G::sim, "s.h5", [](H5Edit& e) { e.remove("/canopy"); }),
         "analyse {I}/s.h5 --out {O}/db.h5", 1, {"s.h5", "/canopy"}});
    add({"simulation species id", h5Case(&G::sim, "s.h5", [](H5Edit& e) { e.setNumber("/snapshots/year_0003/species_id", 0, 99); }),
         "analyse {I}/s.h5 --out {O}/db.h5", 1, {"s.h5", "/snapshots/year_0003/species_id", "99"}});
    add({"simulation NaN x", h5Case(&G::sim, "s.h5", [=](H5Edit& e) { e.setNumber("/snapshots/year_0003/x", 0, nan); }),
         "analyse {I}/s.h5 --out {O}/db.h5", 1, {"s.h5", "/snapshots/year_0003", "plant 0"}});
    add({"simulation negative height", h5Case(&G::sim, "s.h5", [](H5Edit& e) { e.setNumber("/snapshots/year_0003/height", 0, -1); }),
         "analyse {I}/s.h5 --out {O}/db.h5", 1, {"s.h5", "/snapshots/year_0003", "plant 0"}});
    add({"simulation arrays differ", h5Case(&G::sim, "s.h5", [](H5Edit& e) { e.truncate("/snapshots/year_0003/height", 4); }),
         "analyse {I}/s.h5 --out {O}/db.h5", 1, {"s.h5", "differ in length"}});
    add({"simulation without snapshot", h5Case(&G::sim, "s.h5", [](H5Edit& e) { e.remove("/snapshots/year_0003"); }),
         "analyse {I}/s.h5 --out {O}/db.h5", 1, {"s.h5", "/snapshots"}});
    add({"simulation year not there", nullptr, "analyse {S} --out {O}/db.h5 --year 99", 1, {"sim.h5", "year 99"}});

    // ---- terrains in HDF5 and abiotics files
    add({"terrain NaN cell", h5Case(&G::terrainH5, "t.h5", [=](H5Edit& e) { e.setNumber("/terrain/elevation", 5, nan); }),
         "abiotics --terrain {I}/t.h5 --out {O}/a.h5", 1, {"t.h5", "/terrain/elevation", "NaN", "column 5, row 0"}});
    add({"terrain infinite cell", h5Case(&G::terrainH5, "t.h5", [=](H5Edit& e) { e.setNumber("/terrain/elevation", 50, inf); }),
         "abiotics --terrain {I}/t.h5 --out {O}/a.h5", 1, {"t.h5", "infinite", "column 2, row 1"}});
    add({"terrain no elevation", h5Case(&G::terrainH5, "t.h5", [](H5Edit& e) { e.remove("/terrain/elevation"); }),
         "abiotics --terrain {I}/t.h5 --out {O}/a.h5", 1, {"t.h5", "/terrain/elevation"}});
    add({"terrain cell size 0", h5Case(&G::terrainH5, "t.h5", [](H5Edit& e) { e.setAttr("/terrain/elevation", "cell_size_m", 0); }),
         "abiotics --terrain {I}/t.h5 --out {O}/a.h5", 1, {"t.h5", "cell_size_m 0", "[0.001, 10000]"}});
    add({"terrain cell size 1e-300",
         h5Case(&G::terrainH5, "t.h5", [](H5Edit& e) { e.setAttr("/terrain/elevation", "cell_size_m", 1e-300); }),
         "abiotics --terrain {I}/t.h5 --out {O}/a.h5", 1, {"t.h5", "cell_size_m 1e-300"}});
    add({"terrain NaN cell size", h5Case(&G::terrainH5, "t.h5", [=](H5Edit& e) { e.setAttr("/terrain/elevation", "cell_size_m", nan); }),
         "abiotics --terrain {I}/t.h5 --out {O}/a.h5", 1, {"t.h5", "cell_size_m nan"}});
    add({"abiotics NaN sun", h5Case(&G::abiotics, "a.h5", [=](H5Edit& e) { e.setNumber("/sun", 7, nan); }),
         "simulate --abiotics {I}/a.h5 --canopy {C} --years 1 --out {O}/s.h5", 1,
         {"a.h5", "/sun (month 0)", "nan", "column 7, row 0"}});
    add({"abiotics negative moisture", h5Case(&G::abiotics, "a.h5", [](H5Edit& e) { e.setNumber("/moisture", 9, -50); }),
         "synth --terrain {T} --canopy {C} --database {D} --abiotics {I}/a.h5 --out {O}/s.h5", 1,
         {"a.h5", "/moisture (month 0)", "-50"}});
    add({"abiotics infinite temperature", h5Case(&G::abiotics, "a.h5", [=](H5Edit& e) { e.setNumber("/temperature", 3, inf); }),
         "canopy --terrain {T} --chm {CHM} --abiotics {I}/a.h5 --out {O}/c.h5", 1, {"a.h5", "/temperature", "inf"}});
    add({"abiotics sun above 24 h", h5Case(&G::abiotics, "a.h5", [](H5Edit& e) { e.setNumber("/sun", 48 * 48 * 5 + 1, 30); }),
         "simulate --abiotics {I}/a.h5 --canopy {C} --years 1 --out {O}/s.h5", 1, {"a.h5", "/sun (month 5)", "30", "[0, 24]"}});
    add({"abiotics slope above 90", h5Case(&G::abiotics, "a.h5", [](H5Edit& e) { e.setNumber("/slope", 0, 120); }),
         "simulate --abiotics {I}/a.h5 --canopy {C} --years 1 --out {O}/s.h5", 1, {"a.h5", "/slope", "120"}});
    add({"abiotics slope of wrong shape", h5Case(&G::abiotics, "a.h5", [](H5Edit& e) { e.truncate("/slope", 100); }),
         "simulate --abiotics {I}/a.h5 --canopy {C} --years 1 --out {O}/s.h5", 1, {"a.h5", "/slope", "[100]"}});
    add({"abiotics without sun", h5Case(&G::abiotics, "a.h5", [](H5Edit& e) { e.remove("/sun"); }),
         "simulate --abiotics {I}/a.h5 --canopy {C} --years 1 --out {O}/s.h5", 1, {"a.h5", "/sun", "missing"}});
    add({"terrain given as abiotics", nullptr, "simulate --abiotics {T} --canopy {C} --years 1 --out {O}/s.h5", 1,
         {"t.h5", "not an eco-abiotics file"}});
    add({"scene NaN plant", h5Case(&G::scene, "sc.h5", [=](H5Edit& e) { e.setNumber("/undergrowth/x", 0, nan); }),
         "compare {I}/sc.h5 {D} --out {O}/c.md", 1, {"sc.h5", "/undergrowth", "plant 0"}});
    add({"scene species id", h5Case(&G::scene, "sc.h5", [](H5Edit& e) { e.setNumber("/undergrowth/species_id", 0, 77); }),
         "compare {I}/sc.h5 {D} --out {O}/c.md", 1, {"sc.h5", "/undergrowth/species_id", "77"}});
    add({"scene arrays differ", h5Case(&G::scene, "sc.h5", [](H5Edit& e) { e.truncate("/undergrowth/height", 5); }),
         "compare {I}/sc.h5 {D} --out {O}/c.md", 1, {"sc.h5", "differ in length"}});
    add({"not an HDF5 file", textCase("x.h5", "this is text, not HDF5\n"), "inspect {I}/x.h5", 1, {"x.h5"}});
    add({"truncated HDF5 file",
         [](const GoodInputs& g, const CaseDirs& d) { writeText(d.file("db.h5"), readText(g.db).substr(0, 3000)); },
         "inspect {I}/db.h5", 1, {"db.h5", "truncated or damaged"}});

    // ---- ESRI ASCII grids
    const std::string convert = "terrain convert {I}/x.asc {O}/x.h5";
    add({"asc too few values", textCase("x.asc", ascHeader("4", "3", "1") + "1 2 3 4\n1 2 3 4\n"), convert, 1,
         {"x.asc", "4 x 3 = 12 values", "has 8"}});
    add({"asc too many values", textCase("x.asc", ascHeader("4", "3", "1") + kRows + "5 5\n"), convert, 1,
         {"x.asc", "has 14"}});
    add({"asc word value", textCase("x.asc", ascHeader("4", "3", "1") + "1 2 x 4\n1 2 3 4\n1 2 3 4\n"), convert, 1,
         {"x.asc", "line 6", "'x'", "column 3, row 1"}});
    add({"asc infinite value", textCase("x.asc", ascHeader("4", "3", "1") + "1 2 inf 4\n1 2 3 4\n1 2 3 4\n"), convert, 1,
         {"x.asc", "infinite elevation", "column 2, row 2"}});
    add({"asc NaN value", textCase("x.asc", ascHeader("4", "3", "1") + "1 2 nan 4\n1 2 3 4\n1 2 3 4\n"), convert, 1,
         {"x.asc", "NaN elevation"}});
    add({"asc float overflow", textCase("x.asc", ascHeader("4", "3", "1") + "1 2 1e39 4\n1 2 3 4\n1 2 3 4\n"), convert, 1,
         {"x.asc", "'1e39'"}});
    add({"asc negative ncols", textCase("x.asc", ascHeader("-4", "3", "1") + kRows), convert, 1, {"x.asc", "ncols", "-4"}});
    add({"asc fractional ncols", textCase("x.asc", ascHeader("4.5", "3", "1") + kRows), convert, 1, {"x.asc", "ncols", "4.5"}});
    add({"asc zero nrows", textCase("x.asc", ascHeader("4", "0", "1") + kRows), convert, 1, {"x.asc", "nrows", "0"}});
    add({"asc huge ncols", textCase("x.asc", ascHeader("2e9", "3", "1") + kRows), convert, 1, {"x.asc", "ncols", "2e+09"}});
    add({"asc cell size 0", textCase("x.asc", ascHeader("4", "3", "0") + kRows), convert, 1, {"x.asc", "cellsize 0"}});
    add({"asc negative cell size", textCase("x.asc", ascHeader("4", "3", "-1") + kRows), convert, 1, {"x.asc", "cellsize -1"}});
    add({"asc NaN cell size", textCase("x.asc", ascHeader("4", "3", "nan") + kRows), convert, 1, {"x.asc", "cellsize", "'nan'"}});
    add({"asc cell size 1e-300", textCase("x.asc", ascHeader("4", "3", "1e-300") + kRows), convert, 1,
         {"x.asc", "cellsize 1e-300", "[0.001, 10000]"}});
    add({"asc no ncols", textCase("x.asc", "nrows 3\nxllcorner 0\nyllcorner 0\ncellsize 1\n" + kRows), convert, 1,
         {"x.asc", "'ncols'"}});
    add({"asc header too big for memory", textCase("x.asc", ascHeader("9000000", "9000000", "1") + kRows), convert, 1,
         {"x.asc", "9000000 x 9000000", "GB"}});
    add({"asc nodata cell", textCase("x.asc", ascHeader("4", "3", "1") + "NODATA_value -9999\n1 2 -9999 4\n1 2 3 4\n1 2 3 4\n"),
         convert, 1, {"x.asc", "NODATA value -9999", "column 2, row 2"}});
    add({"asc key twice", textCase("x.asc", "ncols 4\nncols 5\nnrows 3\nxllcorner 0\nyllcorner 0\ncellsize 1\n" + kRows),
         convert, 1, {"x.asc", "'ncols' appears twice"}});
    add({"asc word corner", textCase("x.asc", "ncols 4\nnrows 3\nxllcorner abc\nyllcorner 0\ncellsize 1\n" + kRows), convert, 1,
         {"x.asc", "'xllcorner'", "'abc'"}});
    add({"asc empty file", textCase("x.asc", ""), convert, 1, {"x.asc", "'ncols'"}});
    add({"asc binary garbage", textCase("x.asc", std::string("\0\1\2garbage\xff", 11)), convert, 1, {"x.asc"}});
    add({"terrain file missing", nullptr, "terrain convert {I}/none.asc {O}/x.h5", 1, {"none.asc"}});
    add({"terrain is a directory", nullptr, "terrain convert {I} {O}/x.h5", 1, {}});
    add({"unknown output format", nullptr, "terrain convert {TA} {O}/x.xyz", 1, {"x.xyz", "'.xyz'"}});

    // ---- images
    const std::string convertPng = "terrain convert {I}/x.png {O}/x.h5 --cell-size 1";
    add({"png truncated", [](const GoodInputs& g, const CaseDirs& d) { writeText(d.file("x.png"), readText(g.terrainPng).substr(0, 300)); },
         convertPng, 1, {"x.png", "truncated"}});
    add({"png not an image", textCase("x.png", "ncols 4\n"), convertPng, 1, {"x.png", "cannot read image"}});
    add({"png empty", textCase("x.png", ""), convertPng, 1, {"x.png", "cannot read image"}});
    add({"png bad checksum",
         [](const GoodInputs& g, const CaseDirs& d) {
             std::string png = readText(g.terrainPng);
             png[30] = static_cast<char>(png[30] ^ 0x5a);  // inside IHDR
             writeText(d.file("x.png"), png);
         },
         convertPng, 1, {"x.png", "CRC"}});
    add({"png without cell size", nullptr, "terrain convert {TP} {O}/x.h5", 1, {"t.png", "--cell-size"}});
    add({"tif not an image", textCase("x.tif", "hello"), "terrain convert {I}/x.tif {O}/x.h5 --cell-size 1", 1, {"x.tif"}});
    add({"mask not an image", textCase("m.png", "hello"), canopy + " --target Redwood=0.5 --mask {I}/m.png", 1,
         {"m.png", "cannot read image"}});
    add({"sketch of another size", nullptr, "chm generate --terrain {T} --out {O}/c.h5 --sketch {I}/s.png", 1, {"s.png"}});
    c.back().make = [](const GoodInputs&, const CaseDirs& d) {
        REQUIRE(runEco("terrain generate --width 20 --height 20 --cell-size 1 --out " + d.file("s.png")).exitCode == 0);
    };
    c.back().fragments = {"s.png", "20 x 20 pixels", "48 x 48 cells"};

    // ---- biome TOML (eco abiotics --biome)
    const std::string withBiome = "abiotics --terrain {T} --biome {I}/b.toml --out {O}/a.h5";
    add({"biome TOML syntax", biomeCase("[climate]", "[climate"), withBiome, 1, {"b.toml:8", "invalid TOML"}});
    add({"biome unknown key", biomeCase("latitude_deg = 38.58", "latitude_deg = 38.58\nlongitude = 3"), withBiome, 1,
         {"b.toml:10", "'longitude'", "unknown key"}});
    add({"biome missing key", biomeCase("latitude_deg = 38.58\n", ""), withBiome, 1, {"b.toml", "'latitude_deg'", "missing"}});
    add({"biome wrong type", biomeCase("latitude_deg = 38.58", "latitude_deg = \"north\""), withBiome, 1,
         {"b.toml:9", "'latitude_deg'", "expected a number"}});
    add({"biome latitude", biomeCase("latitude_deg = 38.58", "latitude_deg = 123"), withBiome, 1,
         {"b.toml:9", "'latitude_deg'", "123"}});
    add({"biome lapse rate", biomeCase("lapse_rate_c_per_km = 9.8", "lapse_rate_c_per_km = 1e300"), withBiome, 1,
         {"b.toml", "'lapse_rate_c_per_km'", "1e+300"}});
    add({"biome 11 temperatures", biomeCase("temperature_c = [13.5, 16.4,", "temperature_c = [16.4,"), withBiome, 1,
         {"b.toml:12", "'temperature_c'", "got 11"}});
    add({"biome NaN temperature", biomeCase("temperature_c = [13.5,", "temperature_c = [nan,"), withBiome, 1,
         {"b.toml:12", "'temperature_c'", "not finite"}});
    add({"biome hot month", biomeCase("temperature_c = [13.5,", "temperature_c = [1e6,"), withBiome, 1,
         {"b.toml:12", "'temperature_c'", "1e+06"}});
    add({"biome negative rainfall", biomeCase("rainfall_mm = [201.3,", "rainfall_mm = [-201.3,"), withBiome, 1,
         {"b.toml:14", "'rainfall_mm'", "-201.3"}});
    add({"biome sky clarity", biomeCase("sky_clarity = [0.43,", "sky_clarity = [1.43,"), withBiome, 1,
         {"b.toml:17", "'sky_clarity'", "1.43"}});
    add({"biome runoff", biomeCase("runoff_limit_mm = 100.0", "runoff_limit_mm = -1.0"), withBiome, 1,
         {"b.toml:20", "'runoff_limit_mm'", "-1"}});
    add({"biome slope max", biomeCase("slope_max_deg = 55.0", "slope_max_deg = 3.0"), withBiome, 1,
         {"b.toml:22", "'slope_max_deg'", "slope_threshold_deg"}});
    add({"biome evaporation", biomeCase("evaporation_fraction = 0.25", "evaporation_fraction = 2.5"), withBiome, 1,
         {"b.toml:23", "'evaporation_fraction'", "2.5"}});
    add({"biome saturation", biomeCase("saturation_mm = 180.0", "saturation_mm = 0.0"), withBiome, 1,
         {"b.toml:24", "'saturation_mm'", "0"}});
    add({"biome vigour q", biomeCase("q = 0.01", "q = 1.5"), withBiome, 1, {"b.toml:29", "[vigour]", "'q'", "1.5"}});
    add({"biome vigour p", biomeCase("p = 4.5", "p = -4.5"), withBiome, 1, {"b.toml:30", "'p'", "-4.5"}});
    add({"biome vigour a", biomeCase("a = 0.2\n", "a = -2\n"), withBiome, 1, {"b.toml:28", "'a'", "-2"}});
    add({"biome growth month", biomeCase("S = [11, 0, 1, 2, 3, 4]", "S = [11, 0, 1, 2, 3, 14]"), withBiome, 1,
         {"b.toml:34", "'S'", "month 14"}});
    add({"biome empty growth period", biomeCase("S = [11, 0, 1, 2, 3, 4]", "S = []"), withBiome, 1, {"b.toml:34", "'S'"}});
    add({"biome allometry factor", biomeCase("linear_factor = 4.0", "linear_factor = -4.0"), withBiome, 1,
         {"b.toml:51", "'linear_factor'", "-4"}});
    add({"biome unknown allometry", biomeCase("allometry = \"E\"", "allometry = \"Z\""), withBiome, 1,
         {"b.toml:84", "'Redwood Sorrel'", "'Z'"}});
    add({"biome unknown growth period", biomeCase("growth_period = \"L\"", "growth_period = \"Q\""), withBiome, 1,
         {"b.toml:83", "'growth_period'", "'Q'"}});
    add({"biome sub-biome number", biomeCase("number = 4", "number = 40"), withBiome, 1, {"b.toml:69", "'number'", "40"}});
    add({"biome unknown canopy species", biomeCase("canopy = [\"Gray Pine\"]", "canopy = [\"Grey Pine\"]"), withBiome, 1,
         {"b.toml", "'canopy'", "'Grey Pine'"}});
    add({"biome species sub-biome", biomeCase("sub_biomes = [1]", "sub_biomes = [9]"), withBiome, 1,
         {"b.toml:75", "'sub_biomes'", "9"}});
    add({"biome duplicate species", biomeCase("name = \"Chamise\"", "name = \"Redwood Sorrel\""), withBiome, 1,
         {"b.toml:102", "duplicate species name"}});
    add({"biome max age 0", biomeCase("max_age_years = 6\n", "max_age_years = 0\n"), withBiome, 1,
         {"b.toml:76", "'max_age_years'", "0"}});
    add({"biome max height 1e300", biomeCase("max_height_m = 0.25", "max_height_m = 1e300"), withBiome, 1,
         {"b.toml:77", "'max_height_m'", "1e+300"}});
    add({"biome alpha", biomeCase("alpha = 0.60", "alpha = 1.60"), withBiome, 1, {"b.toml:78", "'alpha'", "1.6"}});
    add({"biome sun range 0", biomeCase("sun = { c = 3.5, r = 7 }", "sun = { c = 3.5, r = 0 }"), withBiome, 1,
         {"b.toml:79", "sun", "'r'", "0"}});
    add({"biome NaN optimum", biomeCase("sun = { c = 3.5, r = 7 }", "sun = { c = nan, r = 7 }"), withBiome, 1,
         {"b.toml:79", "'c'", "not finite"}});
    add({"biome empty name", biomeCase("name = \"Redwood Sorrel\"", "name = \"\""), withBiome, 1, {"b.toml:74", "'name'"}});
    add({"biome key twice", biomeCase("latitude_deg = 38.58", "latitude_deg = 38.58\nlatitude_deg = 38.0"), withBiome, 1,
         {"b.toml:10", "latitude_deg"}});
    add({"biome empty file", textCase("b.toml", ""), withBiome, 1, {"b.toml", "'biome'", "missing"}});
    add({"biome binary", textCase("b.toml", std::string("\0\xff\xfe[[[", 6)), withBiome, 1, {"b.toml:1", "invalid TOML"}});

    // ---- simulation configuration (eco simulate --config)
    const std::string simCfg = "simulate --config {I}/sim.toml";
    add({"sim years 0", simConfigCase("", ""), simCfg, 1, {"sim.toml", "years", "0"}});
    c.back().make = [](const GoodInputs& g, const CaseDirs& d) {
        simConfigCase("", "")(g, d);
        writeText(d.file("sim.toml"), replaceOnce(readText(d.file("sim.toml")), "years = 2", "years = 0"));
    };
    add({"sim fractional years", simConfigCase("", ""), simCfg, 1, {"sim.toml:5", "'years'", "integer"}});
    c.back().make = [](const GoodInputs& g, const CaseDirs& d) {
        simConfigCase("", "")(g, d);
        writeText(d.file("sim.toml"), replaceOnce(readText(d.file("sim.toml")), "years = 2", "years = 2.5"));
    };
    add({"sim unknown key", simConfigCase("bogus = 1", ""), simCfg, 1, {"sim.toml:6", "'bogus'", "unknown key"}});
    add({"sim cell size 0", simConfigCase("", "cell_size_m = 0"), simCfg, 1, {"sim.toml", "'cell_size_m'", "0"}});
    add({"sim seeding month", simConfigCase("", "seeding_month = 12"), simCfg, 1, {"sim.toml", "'seeding_month'", "12"}});
    add({"sim growth rule", simConfigCase("", "growth_rule = \"fast\""), simCfg, 1, {"sim.toml", "'growth_rule'", "'fast'"}});
    add({"sim seed radii", simConfigCase("", "seed_outer_radius_factor = 1.0"), simCfg, 1,
         {"sim.toml", "'seed_outer_radius_factor'", "seed_inner_radius_factor"}});
    add({"sim seeding probability", simConfigCase("", "seeding_probability = -1.0"), simCfg, 1,
         {"sim.toml", "'seeding_probability'", "-1"}});
    add({"sim crop reversed", simConfigCase("crop = [10, 10, 5, 5]", ""), simCfg, 1, {"sim.toml:6", "'crop'"}});
    add({"sim crop outside", simConfigCase("crop = [1000, 1000, 2000, 2000]", ""), simCfg, 1, {"1000", "2000", "abiotics"}});
    add({"sim negative seed", simConfigCase("seed = -1", ""), simCfg, 1, {"sim.toml:6", "'seed'"}});
    add({"sim missing abiotics", [](const GoodInputs& g, const CaseDirs& d) {
             simConfigCase("", "")(g, d);
             writeText(d.file("sim.toml"), replaceOnce(readText(d.file("sim.toml")), g.abiotics, d.in + "/none.h5"));
         },
         simCfg, 1, {"none.h5"}});
    add({"sim no canopy", nullptr, "simulate --abiotics {A} --years 1 --out {O}/s.h5", 1, {"canopy"}});
    add({"sim initial plants without columns", nullptr, simulate + " --initial {P}", 1, {"points.csv", "'x_m'"}});

    // ---- canopy placer configuration and targets
    add({"canopy config move factor", textCase("c.toml", "[canopy]\nmove_factor = 5\n"), canopy + " --config {I}/c.toml", 1,
         {"c.toml", "'move_factor'", "5"}});
    add({"canopy config unknown key", textCase("c.toml", "[canopy]\nwhatever = 1\n"), canopy + " --config {I}/c.toml", 1,
         {"c.toml:2", "'whatever'", "unknown key"}});
    add({"canopy config NaN", textCase("c.toml", "[canopy]\nmin_visible_fraction = nan\n"), canopy + " --config {I}/c.toml", 1,
         {"c.toml:2", "'min_visible_fraction'", "not finite"}});
    add({"canopy config iterations", textCase("c.toml", "[canopy]\nmax_iterations = -1\n"), canopy + " --config {I}/c.toml", 1,
         {"c.toml", "'max_iterations'", "-1"}});
    add({"canopy target unknown species", nullptr, canopy + " --target Pinetree=0.5", 1, {"'Pinetree'", "unknown species"}});
    add({"canopy target not canopy", nullptr, canopy + " --target \"Western Swordfern=0.5\"", 1,
         {"'Western Swordfern'", "not a canopy species"}});
    add({"canopy CHM of other cells", textCase("chm.asc", ascHeader("4", "3", "1") + kRows),
         "canopy --terrain {T} --chm {I}/chm.asc --abiotics {A} --out {O}/c.h5", 1, {"chm.asc", "4 x 3", "48 x 48"}});

    // ---- eco run configuration
    add({"run years 0", runConfigCase([](std::string s) { return replaceOnce(s, "years = 2", "years = 0"); }),
         "run {I}/run.toml", 1, {"run.toml", "years"}});
    add({"run kmax 0", runConfigCase([](std::string s) { return replaceOnce(s, "[analyse]", "[analyse]\nkmax = 0"); }),
         "run {I}/run.toml", 1, {"run.toml", "kmax"}});
    add({"run unknown key", runConfigCase([](std::string s) { return replaceOnce(s, "[chm]", "[chm]\nfoo = 1"); }),
         "run {I}/run.toml", 1, {"run.toml:9", "'foo'", "unknown key"}});
    add({"run no [run] table", runConfigCase([](std::string s) { return replaceOnce(s, "[run]", "[runn]"); }),
         "run {I}/run.toml", 1, {"run.toml", "'run'"}});
    add({"run cell size", runConfigCase([](std::string s) { return replaceOnce(s, "cell_size_m = 1.0", "cell_size_m = 1e-300"); }),
         "run {I}/run.toml", 1, {"run.toml", "cell_size_m", "1e-300"}});
    add({"run width 1", runConfigCase([](std::string s) { return replaceOnce(s, "width = 48", "width = 1"); }),
         "run {I}/run.toml", 1, {"run.toml:5", "'width'", "1"}});
    add({"run target fraction", runConfigCase([](std::string s) { return replaceOnce(s, "[canopy]", "[canopy]\ntargets = [\"Redwood=2\"]"); }),
         "run {I}/run.toml", 1, {"run.toml", "Redwood", "2"}});
    add({"run missing sim config",
         runConfigCase([](std::string s) { return replaceAll(s, "config = \"", "config = \"/nonexistent"); }),
         "run {I}/run.toml", 1, {"run.toml", "simulate", "/nonexistent"}});
    add({"run negative seed", runConfigCase([](std::string s) { return replaceOnce(s, "seed = 1", "seed = -5"); }),
         "run {I}/run.toml", 1, {"run.toml:3", "'seed'"}});
    add({"run file missing", nullptr, "run {I}/none.toml", 1, {"none.toml", "cannot open"}});

    // ---- point CSV (eco pcf)
    const std::string pcf = "pcf {I}/p.csv --window 0,0,10,10 --out {O}/p.csv";
    add({"pcf one point", textCase("p.csv", "x,y\n1,2\n"), pcf, 1, {"p.csv", "1 point(s)", "at least 2"}});
    add({"pcf no point", textCase("p.csv", "x,y\n"), pcf, 1, {"p.csv", "0 point(s)"}});
    add({"pcf wrong columns", textCase("p.csv", "a,b\n1,2\n3,4\n"), pcf, 1, {"p.csv:1", "columns x and y"}});
    add({"pcf word", textCase("p.csv", "x,y\n1,abc\n3,4\n"), pcf, 1, {"p.csv:2", "column y", "'abc'"}});
    add({"pcf NaN", textCase("p.csv", "x,y\n1,nan\n3,4\n"), pcf, 1, {"p.csv:2", "column y", "'nan'"}});
    add({"pcf extra field", textCase("p.csv", "x,y\n1,2,3\n3,4\n"), pcf, 1, {"p.csv:2", "found 3"}});
    add({"pcf short row", textCase("p.csv", "x,y\n1\n3,4\n"), pcf, 1, {"p.csv:2", "found 1"}});
    add({"pcf empty file", textCase("p.csv", ""), pcf, 1, {"p.csv:1"}});
    add({"pcf rmax beyond half window", nullptr, "pcf {P} --window 0,0,10,10 --rmax 8 --out {O}/p.csv", 1, {"rmax 8", "5 m"}});

    // ---- outputs that are inputs
    add({"analyse onto its simulation", [](const GoodInputs& g, const CaseDirs& d) { fs::copy_file(g.sim, d.file("s.h5")); },
         "analyse {I}/s.h5 --out {I}/s.h5", 1, {"--out", "s.h5", "is the input"}});
    add({"synth onto its database", [](const GoodInputs& g, const CaseDirs& d) { fs::copy_file(g.db, d.file("db.h5")); },
         "synth --terrain {T} --canopy {C} --database {I}/db.h5 --abiotics {A} --out {I}/db.h5", 1, {"--out", "is the input"}});
    add({"convert onto itself", [](const GoodInputs& g, const CaseDirs& d) { fs::copy_file(g.terrainAsc, d.file("t.asc")); },
         "terrain convert {I}/t.asc {I}/t.asc", 1, {"OUT", "is the input"}});
    add({"canopy csv onto its terrain", [](const GoodInputs& g, const CaseDirs& d) { fs::copy_file(g.terrainAsc, d.file("t.asc")); },
         "canopy --terrain {I}/t.asc --chm {CHM} --abiotics {A} --out {O}/c.h5 --csv {I}/t.asc", 1, {"--csv", "is the input"}});

    // ---- flags: usage errors (exit 2), named by the flag
    add({"threads too many", nullptr, "--threads 100000 pcf {P} --window 0,0,10,10", 2, {"--threads", "1024"}});
    add({"synth refine sweeps", nullptr, synth + " --refine --refine-sweeps -3", 2, {"--refine-sweeps", "-3"}});
    add({"synth max passes", nullptr, synth + " --max-passes 0", 2, {"--max-passes", "[1, 10000]", "0"}});
    add({"synth trunk exclusion", nullptr, synth + " --trunk-exclusion -1", 2, {"--trunk-exclusion", "-1"}});
    add({"synth litter alpha", nullptr, synth + " --litter-full-alpha 0", 2, {"--litter-full-alpha", "0"}});
    add({"synth method", nullptr, synth + " --method magic", 2, {"--method", "'magic'", "structured"}});
    add({"synth zoom", nullptr, synth + " --png {O}/png --zoom 1,2", 2, {"--zoom", "'1,2'"}});
    add({"synth refine window outside", nullptr, synth + " --refine --refine-window 500,500,600,600", 1,
         {"--refine-window", "outside the terrain"}});
    add({"synth refine rmax", nullptr, synth + " --refine --refine-rmax -2", 2, {"--refine-rmax", "-2"}});
    add({"synth refine move NaN", nullptr, synth + " --refine --refine-move nan", 2, {"--refine-move", "'nan'"}});
    add({"synth inner radius NaN", nullptr, synth + " --seed-inner-radius-factor nan", 2,
         {"--seed-inner-radius-factor", "'nan'"}});
    add({"synth terrain of other cells", nullptr, "synth --terrain {I}/x.asc --canopy {C} --database {D} --out {O}/s.h5", 1,
         {"can.h5", "x.asc", "4 x 3"}});
    c.back().make = textCase("x.asc", ascHeader("4", "3", "1") + kRows);
    add({"analyse kmax", nullptr, "analyse {S} --out {O}/db.h5 --kmax 0", 2, {"--kmax", "0"}});
    add({"analyse bins", nullptr, "analyse {S} --out {O}/db.h5 --bins 0", 2, {"--bins", "0"}});
    add({"analyse rmax beyond the plot", nullptr, "analyse {S} --out {O}/db.h5 --rmax 1e12", 1, {"rmax", "1e+12"}});
    add({"analyse abiotics count", nullptr, "analyse {S} --out {O}/db.h5 --abiotics {A} {A}", 1, {"--abiotics", "got 2"}});
    add({"analyse no simulation", nullptr, "analyse --out {O}/db.h5", 2, {}});
    add({"compare window", nullptr, "compare {SC} {D} --window 5,5,1,1 --out {O}/c.md", 2, {"--window", "5,5,1,1"}});
    add({"compare pcf sources", nullptr, "compare {SC} {D} --pcf-sources -1 --out {O}/c.md", 2, {"--pcf-sources"}});
    add({"inspect max pairs", nullptr, "inspect {D} --max-pairs 0", 2, {"--max-pairs", "0"}});
    add({"pcf window", nullptr, "pcf {P} --window 0,0,-10,10 --out {O}/p.csv", 2, {"--window", "0,0,-10,10"}});
    add({"pcf window of 3 numbers", nullptr, "pcf {P} --window 0,0,10 --out {O}/p.csv", 2, {"--window", "'0,0,10'"}});
    add({"pcf bins 0", nullptr, "pcf {P} --window 0,0,10,10 --bins 0 --out {O}/p.csv", 2, {"--bins", "0"}});
    add({"simulate crop", nullptr, simulate + " --crop 1,2,3", 2, {"--crop", "'1,2,3'"}});
    add({"simulate snapshot years", nullptr, simulate + " --snapshot-years 1,x", 2, {"--snapshot-years", "'1,x'"}});
    add({"simulate growth rule", nullptr, simulate + " --growth-rule slow", 2, {"--growth-rule", "'slow'", "ideal"}});
    add({"simulate competition", nullptr, simulate + " --competition war", 2, {"--competition", "'war'"}});
    add({"simulate years 0", nullptr, simulate + " --years 0", 2, {"--years", "0"}});
    add({"simulate model cell size", nullptr, simulate + " --cell-size-m 0", 2, {"--cell-size-m", "(0.001, 10]", "0"}});
    add({"simulate model seeding month", nullptr, simulate + " --seeding-month 12", 2, {"--seeding-month", "12"}});
    add({"simulate canopy limit", nullptr, simulate + " --canopy-limit maybe", 2, {"--canopy-limit", "'maybe'", "canopy_only"}});
    add({"simulate seed 1e400", nullptr, simulate + " --seed 1e400", 2, {"--seed"}});
    add({"canopy min visible", nullptr, canopy + " --min-visible-fraction 2", 2, {"--min-visible-fraction", "[0, 1]", "2"}});
    add({"canopy ring factor", nullptr, canopy + " --ring-factor -1", 2, {"--ring-factor", "-1"}});
    add({"canopy coverage epsilon NaN", nullptr, canopy + " --coverage-epsilon nan", 2, {"--coverage-epsilon", "'nan'"}});
    add({"canopy threshold", nullptr, canopy + " --canopy-threshold -3", 2, {"--canopy-threshold", "-3"}});
    add({"canopy iterations", nullptr, canopy + " --max-iterations -1", 2, {"--max-iterations", "-1"}});
    add({"canopy gap rule", nullptr, canopy + " --chm-gaps maybe", 2, {"--chm-gaps", "'maybe'", "fill"}});
    add({"canopy target fraction", nullptr, canopy + " --target Redwood=1.5", 1, {"'Redwood'", "1.5"}});
    add({"canopy target syntax", nullptr, canopy + " --target Redwood", 1, {"'Redwood'", "SPECIES=FRACTION"}});
    add({"chm heights reversed", nullptr, "chm generate --terrain {T} --out {O}/c.h5 --min-height 30 --max-height 10", 2,
         {"--min-height", "--max-height", "30"}});
    add({"chm shares above 1", nullptr, "chm generate --terrain {T} --out {O}/c.h5 --empty-fraction 0.7 --dense-fraction 0.7", 2,
         {"--empty-fraction", "1.4"}});
    add({"chm max height 1e9", nullptr, "chm generate --terrain {T} --out {O}/c.h5 --max-height 1e9", 2,
         {"--max-height", "1e9"}});
    add({"chm dense spacing memory", nullptr, "chm generate --terrain {T} --out {O}/c.h5 --dense-spacing 0.0000001", 1,
         {"GB"}});
    add({"terrain generate relief NaN", nullptr, "terrain generate --out {O}/t.h5 --width 8 --height 8 --relief nan", 2,
         {"--relief", "'nan'"}});
    add({"terrain generate too big", nullptr, "terrain generate --out {O}/t.h5 --width 65536 --height 65536", 1,
         {"65536 x 65536", "GB"}});
    add({"terrain generate cell size", nullptr, "terrain generate --out {O}/t.h5 --cell-size 1e-300", 2,
         {"--cell-size", "[0.001, 10000]", "1e-300"}});
    add({"abiotics sun step 0", nullptr, "abiotics --terrain {T} --out {O}/a.h5 --sun-step 0", 2, {"--sun-step"}});
    add({"validate unknown scenario", nullptr, "validate --quick --only nosuch --out {O}/v", 1, {"--only", "'nosuch'"}});
    add({"validate configs missing", nullptr, "validate --quick --configs {I}/none --out {O}/v", 1, {"none", "--configs"}});
    add({"unknown flag", nullptr, "simulate --no-such-flag", 2, {"--no-such-flag"}});
    add({"unknown command", nullptr, "frobnicate", 2, {"unknown command 'frobnicate'", "synth"}});
    return c;
}

bool startsWith(const std::string& s, const std::string& p) { return s.rfind(p, 0) == 0; }

std::vector<std::string> lines(const std::string& text) {
    std::vector<std::string> out;
    std::istringstream in(text);
    for (std::string l; std::getline(in, l);)
        if (!l.empty()) out.push_back(l);
    return out;
}

/// Regular files anywhere under `dir`.
std::vector<std::string> filesUnder(const std::string& dir) {
    std::vector<std::string> out;
    for (const auto& e : fs::recursive_directory_iterator(dir))
        if (e.is_regular_file()) out.push_back(e.path().string());
    return out;
}

/// Run every case whose index is `part` modulo kCorpusParts: the corpus runs as several test
/// cases so that CTest spreads it over the cores instead of one serial tail (82 s under the
/// sanitizers as one case).
constexpr int kCorpusParts = 3;

void checkCorpusPart(int part) {
    const GoodInputs& g = good();
    const std::vector<BadCase> cases = corpus();
    int refusedAsExpected = 0, tried = 0;
    for (std::size_t i = static_cast<std::size_t>(part); i < cases.size(); i += kCorpusParts) {
        const BadCase& bc = cases[i];
        ++tried;
        TempDir dir("bad_input");
        const CaseDirs d{dir.file("in"), dir.file("out")};
        fs::create_directories(d.in);
        fs::create_directories(d.out);
        if (bc.make) bc.make(g, d);
        const std::string args = expand(bc.args, g, d);
        const auto r = runEco(args);
        INFO("case '" << bc.name << "': eco " << args << "\n--- exit " << r.exitCode << ", output:\n" << r.output);
        CHECK(r.exitCode == bc.exitCode);
        const std::vector<std::string> out = lines(r.output);
        // The message: eco's own line for bad data; CLI11's line (the flag, then the reason) for usage.
        std::vector<std::string> messages;
        for (const std::string& l : out)
            if (startsWith(l, "eco: error: ") || (bc.exitCode == 2 && !startsWith(l, "Run with")))
                messages.push_back(l);
        if (bc.exitCode == 1) CHECK(messages.size() == 1);
        else CHECK(!messages.empty());
        const std::string message = messages.empty() ? std::string() : messages.front();
        for (const std::string& f : bc.fragments) {
            INFO("fragment '" << f << "'");
            CHECK(message.find(f) != std::string::npos);
        }
        for (const std::string& l : out) {
            CHECK_FALSE(startsWith(l, "libpng"));
            CHECK(l.find("internal error") == std::string::npos);
        }
        const std::vector<std::string> left = filesUnder(d.out);
        CHECK(left.empty());
        refusedAsExpected += r.exitCode == bc.exitCode && left.empty();
    }
    INFO(refusedAsExpected << " of " << tried << " cases of part " << part << " refused as expected");
    CHECK(tried > 0);
    CHECK(refusedAsExpected == tried);
}

}  // namespace

TEST_CASE("a corpus of bad inputs has at least 100 cases, each named once", "[cli][bad-input]") {
    const std::vector<BadCase> cases = corpus();
    CHECK(cases.size() >= 100);  // issue 26: at least 100
    std::set<std::string> names;
    for (const BadCase& bc : cases) {
        INFO("case '" << bc.name << "'");
        CHECK(names.insert(bc.name).second);
    }
}
TEST_CASE("a corpus of bad inputs, part 1 of 3: each refused with its exit code, one line naming it, no output", "[cli][bad-input]") {
    checkCorpusPart(0);
}
TEST_CASE("a corpus of bad inputs, part 2 of 3: each refused with its exit code, one line naming it, no output", "[cli][bad-input]") {
    checkCorpusPart(1);
}
TEST_CASE("a corpus of bad inputs, part 3 of 3: each refused with its exit code, one line naming it, no output", "[cli][bad-input]") {
    checkCorpusPart(2);
}
