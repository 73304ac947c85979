// Round trips through the HDF5 layer and its error messages.
#include <catch2/catch.hpp>
#include <hdf5_hl.h>

#include <chrono>
#include <fstream>
#include <iterator>
#include <thread>
#include <string>
#include <vector>

#include "error.h"
#include "h5io.h"
#include "provenance.h"
#include "terrain_io.h"
#include "test_util.h"

using eco::Grid;
using eco::h5::File;
using eco::h5::Handle;

namespace {

Grid<float> sampleGrid(int w, int h, float base) {
    Grid<float> g(w, h, 0.5, 10.0, -20.0);
    for (int iy = 0; iy < h; ++iy)
        for (int ix = 0; ix < w; ++ix) g(ix, iy) = base + 0.25f * ix - 3.0f * iy;
    return g;
}

/// 300 x 170 cells: large enough to be stored compressed in chunks.
Grid<float> largeGrid() {
    Grid<float> g(300, 170, 0.914);
    for (std::size_t i = 0; i < g.size(); ++i) g.data()[i] = static_cast<float>(i % 1013) * 0.37f;
    return g;
}

}  // namespace

TEST_CASE("h5io: float grid round trip keeps values and geometry", "[h5io]") {
    eco::test::TempDir dir("h5_grid");
    const std::string path = dir.file("g.h5");
    const Grid<float> g = sampleGrid(9, 5, 1.5f);
    {
        File f = File::create(path);
        f.writeGrid("/a/b/grid", g, "m");
    }
    const File f = File::openRead(path);
    CHECK(f.exists("/a"));
    CHECK(f.exists("/a/b/grid"));
    CHECK_FALSE(f.exists("/a/c/grid"));
    const Grid<float> r = f.readGrid("/a/b/grid");
    CHECK(r.sameGeometry(g, 0.0));
    CHECK(r.data() == g.data());
    CHECK(f.attrString("/a/b/grid", "units") == "m");
    CHECK(f.attrString("/a/b/grid", "row_order") == "south_to_north");
    CHECK(f.attrInt("/a/b/grid", "width") == 9);
    CHECK(f.attrInt("/a/b/grid", "height") == 5);
    CHECK(f.shape("/a/b/grid") == std::vector<hsize_t>{5, 9});
    // The grid and its coordinate variables: x and y of the cell centres, world metres,
    // attached to the grid's axes as HDF5 dimension scales (docs/hdf5.md).
    CHECK(f.list("/a/b") == std::vector<std::string>{"grid", "x_m", "y_m"});
    const std::vector<double> xs = f.readF64("/a/b/x_m"), ys = f.readF64("/a/b/y_m");
    REQUIRE(xs.size() == 9);
    REQUIRE(ys.size() == 5);
    CHECK(xs[0] == Approx(g.originX() + 0.5 * g.cellSizeM()));
    CHECK(xs[8] == Approx(g.originX() + 8.5 * g.cellSizeM()));
    CHECK(ys[4] == Approx(g.originY() + 4.5 * g.cellSizeM()));
    CHECK(f.attrString("/a/b/x_m", "units") == "m");
    Handle grid(H5Dopen2(f.id(), "/a/b/grid", H5P_DEFAULT));
    CHECK(H5DSget_num_scales(grid.id(), 0) == 1);
    CHECK(H5DSget_num_scales(grid.id(), 1) == 1);
}

TEST_CASE("h5io: booleans and choices are HDF5 enums, integers int64, and text of older files still reads", "[h5io]") {
    eco::test::TempDir dir("h5_typed");
    const std::string path = dir.file("typed.h5");
    {
        File f = File::create(path);
        f.setAttrBool("/", "yes", true);
        f.setAttrBool("/", "no", false);
        f.setAttrEnum("/", "rule", 1, {"ideal", "literal"});
        f.setAttr("/", "old_bool", std::string("true"));
        f.setAttr("/", "count", std::int64_t{16});
        f.writeI64("/ids", {1, 2, (std::int64_t{1} << 40) + 3}, {3}, "1");
    }
    const File f = File::openRead(path);
    CHECK(f.attrBool("/", "yes"));
    CHECK_FALSE(f.attrBool("/", "no"));
    CHECK(f.attrBool("/", "old_bool"));
    CHECK(f.attrInt("/", "rule") == 1);
    CHECK(f.attrDouble("/", "rule") == 1.0);
    CHECK(f.attrEnumName("/", "rule") == "literal");
    CHECK(f.attrEnumName("/", "yes") == "TRUE");
    CHECK(f.attrInt("/", "count") == 16);
    CHECK_FALSE(f.attrIsString("/", "count"));
    CHECK(f.readI64("/ids") == std::vector<std::int64_t>{1, 2, (std::int64_t{1} << 40) + 3});
    CHECK(f.attrString("/ids", "units") == "1");
    // h5py's boolean: an enum of int8 with the members FALSE = 0 and TRUE = 1.
    Handle a(H5Aopen(f.id(), "yes", H5P_DEFAULT));
    Handle type(H5Aget_type(a.id()));
    REQUIRE(H5Tget_class(type.id()) == H5T_ENUM);
    CHECK(H5Tget_size(type.id()) == 1);
    CHECK(H5Tget_nmembers(type.id()) == 2);
}

TEST_CASE("h5io: large grids (compressed, chunked) round trip", "[h5io]") {
    eco::test::TempDir dir("h5_big");
    const std::string path = dir.file("big.h5");
    const Grid<float> g = largeGrid();
    // A small table and a list of names too: kept in their object headers (compact layout)
    // under its checksum; they were contiguous, unchecked, before.
    std::vector<double> small(300);
    for (std::size_t i = 0; i < small.size(); ++i) small[i] = 0.25 * static_cast<double>(i) + 1.0 / 3.0;
    const std::vector<std::string> names{"Douglas-Fir", "Coast Redwood", "Swordfern", ""};
    {
        File f = File::create(path);
        f.writeGrid("/big", g, "m");
    }
    CHECK(File::openRead(path).readGrid("/big").data() == g.data());
}

TEST_CASE("h5io: stacks and int grids round trip", "[h5io]") {
    eco::test::TempDir dir("h5_stack");
    const std::string path = dir.file("s.h5");
    std::vector<Grid<float>> planes;
    for (int m = 0; m < 12; ++m) planes.push_back(sampleGrid(6, 4, static_cast<float>(m)));
    Grid<std::int32_t> labels(6, 4, 0.5, 10.0, -20.0);
    for (std::size_t i = 0; i < labels.size(); ++i) labels.data()[i] = static_cast<std::int32_t>(i) - 7;
    {
        File f = File::create(path);
        f.writeStack("/maps/sun", planes, "hours/day");
        f.writeGridI32("/maps/labels", labels, "category");
    }
    const File f = File::openRead(path);
    const auto back = f.readStack("/maps/sun");
    REQUIRE(back.size() == 12);
    for (int m = 0; m < 12; ++m) {
        CHECK(back[m].data() == planes[m].data());
        CHECK(back[m].sameGeometry(planes[m], 0.0));
    }
    CHECK(f.shape("/maps/sun") == std::vector<hsize_t>{12, 4, 6});
    const auto l = f.readGridI32("/maps/labels");
    CHECK(l.data() == labels.data());
    CHECK(l.sameGeometry(labels, 0.0));
    // A stack is not a 2-D grid and vice versa.
    CHECK_THROWS_AS(f.readGrid("/maps/sun"), eco::IoError);
    // Planes of different geometry are refused.
    File w = File::create(dir.file("bad.h5"));
    std::vector<Grid<float>> mixed{sampleGrid(6, 4, 0), sampleGrid(4, 6, 0)};
    CHECK_THROWS_AS(w.writeStack("/x", mixed, "m"), eco::ValidationError);
}

TEST_CASE("h5io: 1-D arrays, strings and attributes round trip", "[h5io]") {
    eco::test::TempDir dir("h5_attr");
    const std::string path = dir.file("a.h5");
    const std::vector<std::string> names{"Douglas-Fir", "Coast Redwood", "", "Toyon \xC3\xA9"};
    const std::vector<double> d{1.5, -2.25, 1e-300, 3.0};
    const std::vector<std::int32_t> ints{1, -2, 2147483647};
    {
        File f = File::create(path);
        f.writeStrings("/species/names", names);
        f.writeF64("/species/values", d, {4}, "1");
        f.writeI32("/species/ints", ints, {3}, "1");
        f.writeF32("/species/matrix", {1, 2, 3, 4, 5, 6}, {2, 3}, "1");
        f.setAttr("/", "schema_version", static_cast<std::int64_t>(3));
        f.setAttr("/", "biome", std::string("sonoma"));
        f.setAttr("/species", "lapse_rate_c_per_km", 9.8);
        f.setAttr("/species/values", "bin_edges", std::vector<double>{0, 0.5, 1.0});
        CHECK_THROWS_AS(f.writeF64("/bad", d, {5}, "1"), eco::ValidationError);
    }
    const File f = File::openRead(path);
    CHECK(f.readStrings("/species/names") == names);
    CHECK(f.readF64("/species/values") == d);
    CHECK(f.readI32("/species/ints") == ints);
    std::vector<hsize_t> dims;
    CHECK(f.readF32("/species/matrix", &dims) == std::vector<float>{1, 2, 3, 4, 5, 6});
    CHECK(dims == std::vector<hsize_t>{2, 3});
    CHECK(f.attrInt("/", "schema_version") == 3);
    CHECK(f.attrString("/", "biome") == "sonoma");
    CHECK(f.attrDouble("/species", "lapse_rate_c_per_km") == 9.8);
    CHECK(f.attrDoubles("/species/values", "bin_edges") == std::vector<double>{0, 0.5, 1.0});
    CHECK(f.hasAttr("/species", "lapse_rate_c_per_km"));
    CHECK_FALSE(f.hasAttr("/species", "nope"));
    CHECK_FALSE(f.hasAttr("/nowhere", "nope"));
    const auto children = f.list("/species");
    CHECK(children.size() == 4);
}

TEST_CASE("h5io: a missing dataset or attribute is named in the error", "[h5io]") {
    eco::test::TempDir dir("h5_missing");
    const std::string path = dir.file("m.h5");
    {
        File f = File::create(path);
        f.writeF64("/present", {1.0}, {1}, "1");
    }
    const File f = File::openRead(path);
    CHECK_THROWS_WITH(f.readF64("/absent/values"),
                      Catch::Contains("/absent/values") && Catch::Contains(path) && Catch::Contains("missing"));
    CHECK_THROWS_WITH(f.readGrid("/terrain/elevation"), Catch::Contains("/terrain/elevation"));
    CHECK_THROWS_WITH(f.attrDouble("/present", "cell_size_m"),
                      Catch::Contains("cell_size_m") && Catch::Contains("/present"));
    // Wrong element type.
    CHECK_THROWS_WITH(f.readI32("/present"), Catch::Contains("/present") && Catch::Contains("type"));
    // A 1-D array is not a grid: it has no geometry.
    CHECK_THROWS_AS(f.readGrid("/present"), eco::IoError);
}

TEST_CASE("h5io: a damaged byte anywhere in a file is an error, never a changed value", "[h5io]") {
    // Metadata (superblock, object headers with their attributes, chunk index) carries the
    // HDF5 1.10 format's checksums and every compressed chunk its Fletcher-32: one flipped
    // byte at any offset is refused or lands in unused space, but is never read back as a
    // different value (with the older format a flip in an attribute or a shape was).
    eco::test::TempDir dir("h5_flip");
    const std::string path = dir.file("flip.h5");
    const Grid<float> g = largeGrid();
    // A small table and a list of names too: kept in their object headers (compact layout)
    // under its checksum; they were contiguous, unchecked, before.
    std::vector<double> small(300);
    for (std::size_t i = 0; i < small.size(); ++i) small[i] = 0.25 * static_cast<double>(i) + 1.0 / 3.0;
    const std::vector<std::string> names{"Douglas-Fir", "Coast Redwood", "Swordfern", ""};
    {
        File f = File::create(path);
        f.writeGrid("/big", g, "m");
        f.setAttr("/big", "note", std::string("some text"));
        f.writeF64("/plants/height", small, {small.size()}, "1");
        f.writeStrings("/plants/species_names", names);
    }
    std::string bytes;
    {
        std::ifstream in(path, std::ios::binary);
        bytes.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
    }
    REQUIRE(bytes.size() > 1000);
    std::vector<double> xs, ys;
    {
        const File f = File::openRead(path);
        xs = f.readF64("/x_m");
        ys = f.readF64("/y_m");
    }
    const std::string damaged = dir.file("damaged.h5");
    int refused = 0, same = 0;
    for (std::size_t at = 0; at < bytes.size(); at += 37) {
        std::string copy = bytes;
        copy[at] = static_cast<char>(copy[at] ^ 0x5a);
        {
            std::ofstream out(damaged, std::ios::binary | std::ios::trunc);
            out.write(copy.data(), static_cast<std::streamsize>(copy.size()));
        }
        try {
            const File f = File::openRead(damaged);
            const Grid<float> r = f.readGrid("/big");
            INFO("flipped byte at offset " << at << " of " << bytes.size());
            REQUIRE(r.sameGeometry(g, 0.0));
            REQUIRE(r.data() == g.data());
            REQUIRE(f.attrString("/big", "units") == "m");
            REQUIRE(f.attrString("/big", "note") == "some text");
            const std::vector<double> height = f.readF64("/plants/height");
            const std::vector<std::string> species = f.readStrings("/plants/species_names");
            REQUIRE(height == small);
            REQUIRE(species == names);
            // The grid's coordinate variables (dimension scales) too. (The scales' references,
            // DIMENSION_LIST and REFERENCE_LIST, live in the global heap, which has no
            // checksum; eco's readers never read them.)
            const std::vector<double> xr = f.readF64("/x_m"), yr = f.readF64("/y_m");  // outside REQUIRE: may throw
            REQUIRE(xr == xs);
            REQUIRE(yr == ys);
            ++same;
        } catch (const eco::Error&) {
            ++refused;
        }
    }
    INFO(refused << " refused, " << same << " read back unchanged");
    CHECK(refused > same);
}

TEST_CASE("h5io: a missing or non-HDF5 file gives a clear error", "[h5io]") {
    eco::test::TempDir dir("h5_bad");
    const std::string missing = dir.file("nope.h5");
    CHECK_THROWS_WITH(File::openRead(missing), Catch::Contains(missing) && Catch::Contains("cannot open"));
    const std::string text = dir.file("text.h5");
    {
        std::ofstream o(text);
        o << "this is not an HDF5 file\n";
    }
    CHECK_THROWS_AS(File::openRead(text), eco::IoError);
    CHECK_THROWS_WITH(File::openRead(text), Catch::Contains(text) && Catch::Contains("not an HDF5 file"));
    // Creating in a directory that does not exist.
    CHECK_THROWS_AS(File::create(dir.file("no/such/dir/x.h5")), eco::IoError);
    // A file cut short (an interrupted copy): said, with its size; it was only "cannot open HDF5 file".
    const std::string whole = dir.file("whole.h5"), cut = dir.file("cut.h5");
    eco::writeTerrainH5(whole, eco::Grid<float>(64, 64, 1.0, 0.0, 0.0, 5.0f));
    {
        std::ifstream in(whole, std::ios::binary);
        std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
        REQUIRE(bytes.size() > 2000);
        std::ofstream(cut, std::ios::binary) << bytes.substr(0, bytes.size() / 2);
    }
    CHECK_THROWS_AS(File::openRead(cut), eco::IoError);
    CHECK_THROWS_WITH(File::openRead(cut), Catch::Contains(cut) && Catch::Contains("truncated or damaged") &&
                                               Catch::Contains("interrupted copy"));
}

TEST_CASE("h5io: the same content written at different times has the same bytes, and provenance stays apart", "[h5io][provenance]") {
    eco::test::TempDir dir("h5_bytes");
    const auto write = [&](const std::string& path) {
        File f = File::create(path);
        f.writeGrid("/a/grid", sampleGrid(80, 60, 2.0f), "m");  // chunked and compressed
        f.writeStrings("/a/names", {"x", "yy"});
        f.setAttr("/", "format", std::string("test"));
        eco::writeProvenance(f, {{"wall_time_s", 1.5}, {"threads", std::int64_t{2}}, {"dates", std::string("now")}});
    };
    const auto bytes = [](const std::string& path) {
        std::ifstream in(path, std::ios::binary);
        return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    };
    {
        eco::setProvenanceRecorded(false);
        write(dir.file("one.h5"));
        // HDF5's object times have a resolution of one second.
        std::this_thread::sleep_for(std::chrono::milliseconds(1100));
        write(dir.file("two.h5"));
        eco::setProvenanceRecorded(true);
    }
    CHECK(bytes(dir.file("one.h5")) == bytes(dir.file("two.h5")));
    CHECK_FALSE(File::openRead(dir.file("one.h5")).exists(eco::kProvenanceGroup));

    write(dir.file("prov.h5"));
    const File f = File::openRead(dir.file("prov.h5"));
    CHECK(f.attrDouble(eco::kProvenanceGroup, "wall_time_s") == 1.5);
    CHECK(f.attrInt(eco::kProvenanceGroup, "threads") == 2);
    CHECK(eco::readProvenanceString(f, "dates") == std::string("now"));
    CHECK_FALSE(eco::readProvenanceDouble(f, "missing").has_value());
    // Files written before the group: the value at the root.
    {
        File old = File::create(dir.file("old.h5"));
        old.setAttr("/", "created_utc", std::string("2025-01-01T00:00:00Z"));
    }
    CHECK(eco::readProvenanceString(File::openRead(dir.file("old.h5")), "created_utc", "created_utc") ==
          std::string("2025-01-01T00:00:00Z"));
}

TEST_CASE("h5io: a dataset whose declared shape does not fit in memory is refused before allocating", "[h5io]") {
    // A damaged file may declare any shape; the reader allocated it (std::bad_alloc escaping as
    // an internal error; fuzz_biome_db grew past 1.6 GB on such a file). Chunked storage is
    // allocated lazily, so this file of 2^40 doubles (8.8 TB) is a few KB.
    eco::test::TempDir dir("h5io_huge");
    const std::string path = dir.file("huge.h5");
    {
        const hid_t f = H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
        const hsize_t dims[1] = {hsize_t{1} << 40};
        const hsize_t chunk[1] = {1024};
        const hid_t space = H5Screate_simple(1, dims, nullptr);
        const hid_t plist = H5Pcreate(H5P_DATASET_CREATE);
        H5Pset_chunk(plist, 1, chunk);
        const hid_t ds = H5Dcreate2(f, "/huge", H5T_IEEE_F64LE, space, H5P_DEFAULT, plist, H5P_DEFAULT);
        REQUIRE(ds >= 0);
        const hid_t strings = H5Dcreate2(f, "/names", H5T_C_S1, space, H5P_DEFAULT, plist, H5P_DEFAULT);
        REQUIRE(strings >= 0);
        H5Dclose(strings);
        H5Dclose(ds);
        H5Pclose(plist);
        H5Sclose(space);
        H5Fclose(f);
    }
    const File f = File::openRead(path);
    CHECK_THROWS_AS(f.readF64("/huge"), eco::ValidationError);
    CHECK_THROWS_WITH(f.readF64("/huge"), Catch::Contains("huge.h5") && Catch::Contains("/huge") &&
                                              Catch::Contains("needs about") && Catch::Contains("memory"));
    CHECK_THROWS_WITH(f.readStrings("/names"), Catch::Contains("/names") && Catch::Contains("needs about"));
}

TEST_CASE("h5io: names are written as fixed-length strings, variable-length ones of older files still read", "[h5io]") {
    // Variable-length strings live in the global heap, which has no checksum: a damaged length
    // there made HDF5 allocate 4 GB (fuzz_canopy_file). writeStrings writes fixed-length ones.
    eco::test::TempDir dir("h5io_strings");
    const std::string path = dir.file("s.h5");
    const std::vector<std::string> names{"Coast Redwood", "", "Toyon \xC3\xA9", std::string(200, 'x')};
    {
        File f = File::create(path);
        f.writeStrings("/new", names);
        const hid_t type = H5Tcopy(H5T_C_S1);
        H5Tset_size(type, H5T_VARIABLE);
        const hsize_t n = names.size();
        const hid_t space = H5Screate_simple(1, &n, nullptr);
        const hid_t ds = H5Dcreate2(f.id(), "/old", type, space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
        REQUIRE(ds >= 0);
        std::vector<const char*> ptrs;
        for (const auto& s : names) ptrs.push_back(s.c_str());
        REQUIRE(H5Dwrite(ds, type, H5S_ALL, H5S_ALL, H5P_DEFAULT, ptrs.data()) >= 0);
        H5Dclose(ds);
        H5Sclose(space);
        H5Tclose(type);
    }
    const File f = File::openRead(path);
    CHECK(f.readStrings("/new") == names);
    CHECK(f.readStrings("/old") == names);
    const hid_t ds = H5Dopen2(f.id(), "/new", H5P_DEFAULT);
    const hid_t type = H5Dget_type(ds);
    CHECK(H5Tis_variable_str(type) == 0);
    CHECK(H5Tget_size(type) == 200);
    H5Tclose(type);
    H5Dclose(ds);
}

TEST_CASE("h5io: a string dataset of two dimensions is refused", "[h5io]") {
    // readStrings wrote the sizes of every dimension into one variable (a stack overflow for 2-D).
    eco::test::TempDir dir("h5io_strings2d");
    const std::string path = dir.file("s.h5");
    {
        const hid_t f = H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
        const hsize_t dims[2] = {2, 3};
        const hid_t space = H5Screate_simple(2, dims, nullptr);
        const hid_t type = H5Tcopy(H5T_C_S1);
        H5Tset_size(type, H5T_VARIABLE);
        const hid_t ds = H5Dcreate2(f, "/names", type, space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
        REQUIRE(ds >= 0);
        H5Dclose(ds);
        H5Tclose(type);
        H5Sclose(space);
        H5Fclose(f);
    }
    const File f = File::openRead(path);
    CHECK_THROWS_WITH(f.readStrings("/names"), Catch::Contains("s.h5") && Catch::Contains("one-dimensional"));
}
