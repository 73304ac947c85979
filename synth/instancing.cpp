#include "instancing.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#include "error.h"
#include "rng.h"

namespace eco::synth {

namespace {

struct Point {
    double a = 0, b = 0;  ///< log height, log crown radius
};

double dist2(const Point& p, const Point& q) {
    const double da = p.a - q.a, db = p.b - q.b;
    return da * da + db * db;
}

/// Index of the nearest centre (the lowest index on a tie).
std::size_t nearest(const Point& p, const std::vector<Point>& centres) {
    std::size_t best = 0;
    double bestD = std::numeric_limits<double>::infinity();
    for (std::size_t c = 0; c < centres.size(); ++c) {
        const double d = dist2(p, centres[c]);
        if (d < bestD) {
            bestD = d;
            best = c;
        }
    }
    return best;
}

/// Weighted pick of an index with probability proportional to `mass` (not all zero).
std::size_t pick(const std::vector<double>& mass, RandomStream& rs) {
    const double total = std::accumulate(mass.begin(), mass.end(), 0.0);
    double u = rs.uniform() * total;
    for (std::size_t i = 0; i < mass.size(); ++i) {
        if (u < mass[i]) return i;
        u -= mass[i];
    }
    for (std::size_t i = mass.size(); i-- > 0;)
        if (mass[i] > 0) return i;
    return 0;
}

/// Weighted k-means of one species' points: the centres (at most k) and each point's centre.
std::vector<Point> kMeans(const std::vector<Point>& pts, const std::vector<double>& w, int k, RandomStream& rs, int maxIterations,
                          std::vector<std::size_t>& assignment) {
    const std::size_t n = pts.size();
    // Distinct points: as many as k or fewer is exact, one centre each.
    std::vector<std::size_t> order(n);
    std::iota(order.begin(), order.end(), 0);
    std::sort(order.begin(), order.end(), [&](std::size_t x, std::size_t y) {
        return pts[x].a != pts[y].a ? pts[x].a < pts[y].a : pts[x].b < pts[y].b;
    });
    std::vector<Point> distinct;
    for (std::size_t i : order)
        if (distinct.empty() || distinct.back().a != pts[i].a || distinct.back().b != pts[i].b) distinct.push_back(pts[i]);
    std::vector<Point> centres;
    if (distinct.size() <= static_cast<std::size_t>(k)) {
        centres = distinct;
    } else {
        // k-means++: the first centre by weight, each next by weight x squared distance to the
        // nearest chosen one.
        centres.push_back(pts[pick(w, rs)]);
        std::vector<double> d2(n), mass(n);
        for (std::size_t i = 0; i < n; ++i) d2[i] = dist2(pts[i], centres[0]);
        while (centres.size() < static_cast<std::size_t>(k)) {
            for (std::size_t i = 0; i < n; ++i) mass[i] = w[i] * d2[i];
            if (std::accumulate(mass.begin(), mass.end(), 0.0) <= 0) break;
            centres.push_back(pts[pick(mass, rs)]);
            for (std::size_t i = 0; i < n; ++i) d2[i] = std::min(d2[i], dist2(pts[i], centres.back()));
        }
    }
    assignment.assign(n, 0);
    std::vector<std::size_t> next(n);
    for (int it = 0; it <= maxIterations; ++it) {
#pragma omp parallel for schedule(static)
        for (std::size_t i = 0; i < n; ++i) next[i] = nearest(pts[i], centres);
        if (it > 0 && next == assignment) break;
        assignment.swap(next);
        if (it == maxIterations) break;
        // Weighted means, summed in point order (the same bits for any thread count).
        std::vector<double> sa(centres.size(), 0.0), sb(centres.size(), 0.0), sw(centres.size(), 0.0);
        for (std::size_t i = 0; i < n; ++i) {
            sa[assignment[i]] += w[i] * pts[i].a;
            sb[assignment[i]] += w[i] * pts[i].b;
            sw[assignment[i]] += w[i];
        }
        for (std::size_t c = 0; c < centres.size(); ++c)
            if (sw[c] > 0) centres[c] = {sa[c] / sw[c], sb[c] / sw[c]};
    }
    return centres;
}

}  // namespace

InstancingResult quantisePlants(const std::vector<Plant>& plants, std::size_t speciesCount, const InstancingParams& params) {
    if (params.prototypesPerSpecies < 1 || params.prototypesPerSpecies > 100000)
        throw ValidationError("instancing: prototypes per species must be in 1 .. 100000, got " + std::to_string(params.prototypesPerSpecies));
    if (params.maxIterations < 0) throw ValidationError("instancing: max iterations must not be negative");
    std::vector<std::vector<std::size_t>> bySpecies(speciesCount);
    for (std::size_t i = 0; i < plants.size(); ++i) {
        const Plant& p = plants[i];
        if (p.speciesId < 0 || static_cast<std::size_t>(p.speciesId) >= speciesCount)
            throw ValidationError("instancing: plant " + std::to_string(i) + " has species id " + std::to_string(p.speciesId) + " outside the biome");
        if (!(p.heightM > 0) || !(p.crownRadiusM > 0) || !std::isfinite(p.heightM) || !std::isfinite(p.crownRadiusM))
            throw ValidationError("instancing: plant " + std::to_string(i) + " has no size (height " + std::to_string(p.heightM) + " m, crown radius " +
                                  std::to_string(p.crownRadiusM) + " m)");
        bySpecies[static_cast<std::size_t>(p.speciesId)].push_back(i);
    }
    InstancingResult r;
    r.instances.resize(plants.size());
    r.errorBySpecies.assign(speciesCount, {});
    double sumUnscaled = 0, sumScaled = 0, sumArea = 0, areaUnscaled = 0, areaScaled = 0;
    for (std::size_t s = 0; s < speciesCount; ++s) {
        const std::vector<std::size_t>& idx = bySpecies[s];
        if (idx.empty()) continue;
        std::vector<Point> pts(idx.size());
        std::vector<double> w(idx.size());
        for (std::size_t j = 0; j < idx.size(); ++j) {
            const Plant& p = plants[idx[j]];
            pts[j] = {std::log(p.heightM), std::log(p.crownRadiusM)};
            w[j] = params.weightByCrownArea ? p.crownRadiusM * p.crownRadiusM : 1.0;
        }
        RandomStream rs(params.seed, 0x1a57a9ce00000000ull + s);
        std::vector<std::size_t> assignment;
        const std::vector<Point> centres = kMeans(pts, w, params.prototypesPerSpecies, rs, params.maxIterations, assignment);
        // Prototypes of this species by height; centres without a plant are dropped.
        std::vector<std::size_t> counts(centres.size(), 0);
        for (std::size_t c : assignment) ++counts[c];
        std::vector<std::size_t> used;
        for (std::size_t c = 0; c < centres.size(); ++c)
            if (counts[c] > 0) used.push_back(c);
        std::sort(used.begin(), used.end(), [&](std::size_t x, std::size_t y) {
            return centres[x].a != centres[y].a ? centres[x].a < centres[y].a : centres[x].b < centres[y].b;
        });
        std::vector<int> idOf(centres.size(), -1);
        for (std::size_t c : used) {
            Prototype p;
            p.id = static_cast<int>(r.prototypes.size());
            p.speciesId = static_cast<int>(s);
            p.heightM = std::exp(centres[c].a);
            p.crownRadiusM = std::exp(centres[c].b);
            p.count = counts[c];
            idOf[c] = p.id;
            r.prototypes.push_back(p);
        }
        InstancingError& e = r.errorBySpecies[s];
        double speciesArea = 0;
        for (std::size_t j = 0; j < idx.size(); ++j) {
            const Plant& plant = plants[idx[j]];
            const Prototype& proto = r.prototypes[static_cast<std::size_t>(idOf[assignment[j]])];
            Instance& in = r.instances[idx[j]];
            in.prototype = proto.id;
            in.xM = plant.xM;
            in.yM = plant.yM;
            in.groundZM = plant.groundZM;
            in.rotationDeg = RandomStream(params.seed, 0x0407a7e000000000ull + idx[j]).uniform() * 360.0;
            in.scale = plant.heightM / proto.heightM;
            const double unscaled = std::max(std::fabs(proto.heightM - plant.heightM) / plant.heightM,
                                             std::fabs(proto.crownRadiusM - plant.crownRadiusM) / plant.crownRadiusM);
            const double scaled = std::fabs(proto.crownRadiusM * in.scale - plant.crownRadiusM) / plant.crownRadiusM;
            e.meanUnscaled += unscaled;
            e.meanScaled += scaled;
            e.maxUnscaled = std::max(e.maxUnscaled, unscaled);
            e.maxScaled = std::max(e.maxScaled, scaled);
            const double area = plant.crownRadiusM * plant.crownRadiusM;
            speciesArea += area;
            e.areaMeanUnscaled += area * unscaled;
            e.areaMeanScaled += area * scaled;
        }
        sumArea += speciesArea;
        areaUnscaled += e.areaMeanUnscaled;
        areaScaled += e.areaMeanScaled;
        e.areaMeanUnscaled /= speciesArea;
        e.areaMeanScaled /= speciesArea;
        sumUnscaled += e.meanUnscaled;
        sumScaled += e.meanScaled;
        r.error.maxUnscaled = std::max(r.error.maxUnscaled, e.maxUnscaled);
        r.error.maxScaled = std::max(r.error.maxScaled, e.maxScaled);
        e.meanUnscaled /= static_cast<double>(idx.size());
        e.meanScaled /= static_cast<double>(idx.size());
    }
    if (!plants.empty()) {
        r.error.meanUnscaled = sumUnscaled / static_cast<double>(plants.size());
        r.error.meanScaled = sumScaled / static_cast<double>(plants.size());
        r.error.areaMeanUnscaled = areaUnscaled / sumArea;
        r.error.areaMeanScaled = areaScaled / sumArea;
    }
    return r;
}

}  // namespace eco::synth

// --------------------------------------------------------------------------- eco instance

#include <filesystem>
#include <sstream>

#include <cstring>
#include <fstream>

#include "atomic_file.h"
#include "chart.h"
#include "float_image.h"
#include "geo_raster.h"
#include "h5io.h"
#include "image_out.h"
#include "scene.h"
#include "text_format.h"

namespace eco::synth {

namespace {

template <class T>
void putLittleEndian(std::string& out, T value) {
    unsigned char bytes[sizeof(T)];
    std::memcpy(bytes, &value, sizeof(T));
#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_BIG_ENDIAN__
    std::reverse(bytes, bytes + sizeof(T));
#endif
    out.append(reinterpret_cast<const char*>(bytes), sizeof(T));
}

/// OUT/instances.ply: one vertex per plant (binary little-endian PLY 1.0; the layout is in
/// its header and in docs/export.md), rows in the order of instances.csv.
void writeInstancesPly(const std::string& path, const std::string& scenePath, const std::vector<Plant>& plants,
                       std::size_t canopyCount, const InstancingResult& r, const Biome& biome) {
    std::ostringstream header;
    header << "ply\nformat binary_little_endian 1.0\n"
           << "comment eco instances of " << scenePath << " (docs/export.md)\n"
           << "comment world metres: x east, y north, z up = ground elevation at the plant; float32\n"
           << "comment id = row of instances.csv; layer 1 canopy, 0 undergrowth; species = species_id of the biome\n"
           << "comment prototype = row of prototypes.csv; rotation_deg about the vertical; scale = height / prototype height\n";
    for (std::size_t s = 0; s < biome.species.size(); ++s)
        header << "comment species " << s << " " << biome.species[s].name << "\n";
    header << "element vertex " << plants.size() << "\n"
           << "property float x\nproperty float y\nproperty float z\n"
           << "property uchar red\nproperty uchar green\nproperty uchar blue\n"
           << "property int id\nproperty uchar layer\nproperty ushort species\nproperty int prototype\n"
           << "property float rotation_deg\nproperty float scale\nproperty float height\nproperty float crown_radius\n"
           << "end_header\n";
    std::string body = header.str();
    body.reserve(body.size() + plants.size() * 42);
    for (std::size_t i = 0; i < plants.size(); ++i) {
        const Plant& p = plants[i];
        const Instance& in = r.instances[i];
        putLittleEndian<float>(body, static_cast<float>(p.xM));
        putLittleEndian<float>(body, static_cast<float>(p.yM));
        putLittleEndian<float>(body, static_cast<float>(p.groundZM));
        const Rgb c = categoryColour(p.speciesId);
        for (float v : c) body += static_cast<char>(static_cast<unsigned char>(std::lround(std::clamp(v, 0.f, 1.f) * 255.f)));
        putLittleEndian<std::int32_t>(body, static_cast<std::int32_t>(i));
        body += static_cast<char>(i < canopyCount ? 1 : 0);
        putLittleEndian<std::uint16_t>(body, static_cast<std::uint16_t>(p.speciesId));
        putLittleEndian<std::int32_t>(body, in.prototype);
        putLittleEndian<float>(body, static_cast<float>(in.rotationDeg));
        putLittleEndian<float>(body, static_cast<float>(in.scale));
        putLittleEndian<float>(body, static_cast<float>(p.heightM));
        putLittleEndian<float>(body, static_cast<float>(p.crownRadiusM));
    }
    writeTextFile(path, body);
}

}  // namespace

InstancingSummary runInstancing(const InstancingRun& run) {
    namespace fs = std::filesystem;
    // Error against K, the chosen K marked: K = 1 .. kMax.
    const int kMax = run.curveMaxK > 0 ? run.curveMaxK : std::min(32, std::max(2 * run.params.prototypesPerSpecies, 4));
    const int steps = kMax + 3;  // read, the chosen K, each K of the curve, the outputs
    int done = 0;
    const auto step = [&] {
        if (run.progress) run.progress(++done, steps);
    };
    const Biome biome = [&] {
        if (!run.biome.empty()) return loadBiome(run.biome);
        const h5::File f = h5::File::openRead(run.scene);
        if (!f.hasAttr("/", "biome_toml"))
            throw IoError(run.scene + ": no biome_toml attribute at the root: give the scene's biome with --biome");
        return parseBiome(f.attrString("/", "biome_toml"), run.scene + " (its biome_toml)");
    }();
    const SceneData scene = readSceneFile(run.scene, biome);
    std::vector<Plant> plants = scene.canopy;
    plants.insert(plants.end(), scene.undergrowth.begin(), scene.undergrowth.end());
    if (plants.empty()) throw ValidationError(run.scene + ": the scene has no plants to instance");
    step();
    const InstancingResult r = quantisePlants(plants, biome.species.size(), run.params);
    step();

    ChartSeries meanU, maxU, meanS, chosen;
    meanU.name = "mean, unscaled";
    meanU.colour = {0.12f, 0.47f, 0.71f};
    meanU.strokeOffsetsPx = {0, 1};
    maxU.name = "max, unscaled";
    maxU.colour = {0.12f, 0.47f, 0.71f};
    maxU.strokeOffsetsPx = {0};
    meanS.name = "mean, scaled to height";
    meanS.colour = {0.84f, 0.15f, 0.16f};
    meanS.strokeOffsetsPx = {0, 1};
    ChartSeries areaU;
    areaU.name = "area-weighted mean, unscaled";
    areaU.colour = {0.17f, 0.63f, 0.17f};
    areaU.strokeOffsetsPx = {0, 1};
    chosen.colour = {0, 0, 0};
    chosen.strokeOffsetsPx = {};
    chosen.pointRadiusPx = 5;
    std::ostringstream curve;
    curve << "| K | prototypes | mean error, unscaled | max, unscaled | mean, scaled | max, scaled | area-weighted mean, unscaled | area-weighted, scaled |\n"
             "|---:|---:|---:|---:|---:|---:|---:|---:|\n";
    double top = 0;
    for (int k = 1; k <= kMax; ++k) {
        InstancingParams p = run.params;
        p.prototypesPerSpecies = k;
        const InstancingResult rk = k == run.params.prototypesPerSpecies ? r : quantisePlants(plants, biome.species.size(), p);
        meanU.x.push_back(k);
        meanU.y.push_back(100 * rk.error.meanUnscaled);
        maxU.x.push_back(k);
        maxU.y.push_back(100 * rk.error.maxUnscaled);
        meanS.x.push_back(k);
        meanS.y.push_back(100 * rk.error.meanScaled);
        areaU.x.push_back(k);
        areaU.y.push_back(100 * rk.error.areaMeanUnscaled);
        top = std::max(top, 100 * rk.error.meanUnscaled);
        if (k == run.params.prototypesPerSpecies) {
            chosen.x = {static_cast<double>(k)};
            chosen.y = {100 * rk.error.meanUnscaled};
        }
        curve << "| " << k << (k == run.params.prototypesPerSpecies ? " (chosen)" : "") << " | " << rk.prototypes.size() << " | "
              << formatNumber(100 * rk.error.meanUnscaled, 3) << " % | " << formatNumber(100 * rk.error.maxUnscaled, 3) << " % | "
              << formatNumber(100 * rk.error.meanScaled, 3) << " % | " << formatNumber(100 * rk.error.maxScaled, 3) << " % | "
              << formatNumber(100 * rk.error.areaMeanUnscaled, 3) << " % | " << formatNumber(100 * rk.error.areaMeanScaled, 3) << " % |\n";
        step();
    }

    AtomicOutputSet outputs;
    const auto at = [&](const std::string& name) { return (fs::path(run.outDir) / name).string(); };
    ensureDirectory(run.outDir);
    InstancingSummary summary;
    summary.plants = plants.size();
    summary.prototypes = r.prototypes.size();
    summary.error = r.error;
    {
        std::ostringstream csv;
        csv << "prototype,species_id,species,height_m,crown_radius_m,instances\n";
        for (const Prototype& p : r.prototypes)
            csv << p.id << "," << p.speciesId << "," << csvField(biome.species[static_cast<std::size_t>(p.speciesId)].name) << ","
                << formatNumber(p.heightM, 8) << "," << formatNumber(p.crownRadiusM, 8) << "," << p.count << "\n";
        writeTextFile(at("prototypes.csv"), csv.str());
    }
    {
        std::ostringstream csv;
        // id, species, height_m and crown_radius_m were added at the end (issue 31 item 6), so
        // that readers of the earlier columns by position still work.
        csv << "layer,prototype,species_id,x_m,y_m,ground_z_m,rotation_deg,scale,id,species,height_m,crown_radius_m\n";
        for (std::size_t i = 0; i < r.instances.size(); ++i) {
            const Instance& in = r.instances[i];
            csv << (i < scene.canopy.size() ? "canopy" : "undergrowth") << "," << in.prototype << "," << plants[i].speciesId << ","
                << formatNumber(in.xM, 10) << "," << formatNumber(in.yM, 10) << "," << formatNumber(in.groundZM, 8) << ","
                << formatNumber(in.rotationDeg, 6) << "," << formatNumber(in.scale, 8) << "," << i << ","
                << csvField(biome.species[static_cast<std::size_t>(plants[i].speciesId)].name) << ","
                << formatNumber(plants[i].heightM, 8) << "," << formatNumber(plants[i].crownRadiusM, 8) << "\n";
        }
        writeTextFile(at("instances.csv"), csv.str());
    }
    // For 3D packages (docs/export.md): the plants as a PLY point cloud, the forest floor as
    // float images (OpenEXR) and GeoTIFFs.
    writeInstancesPly(at("instances.ply"), run.scene, plants, scene.canopy.size(), r, biome);
    const std::vector<std::pair<std::string, const Grid<float>*>> floors = {{"grass", &scene.grass}, {"litter", &scene.litter}};
    for (const auto& [name, grid] : floors) {
        if (grid->width() < 1 || grid->height() < 1) continue;
        writeFloatExr(at(name + ".exr"), *grid, "1", name + " density, 0..1 (eco synth forest floor)");
        writeGeoTiff(at(name + ".tif"), *grid, "1");
    }
    if (scene.terrainM.width() >= 1 && scene.terrainM.height() >= 1)
        writeFloatExr(at("terrain.exr"), scene.terrainM, "m", "ground elevation, m (the scene's terrain)");
    // The mean errors on a log axis: they fall over decades with K (the max only shown in the table).
    (void)maxU;
    (void)top;
    for (ChartSeries* c : {&meanU, &meanS, &areaU, &chosen})
        for (double& y : c->y) y = std::log10(std::max(y, 1e-3));
    double lo = 0, hi = 0;
    for (const ChartSeries* c : {&meanU, &meanS, &areaU})
        for (double y : c->y) {
            lo = std::min(lo, y);
            hi = std::max(hi, y);
        }
    Canvas png = chartCanvas({meanU, meanS, areaU, chosen}, 0.5, kMax + 0.5, std::floor(lo), std::ceil(hi) + 0.01, "prototypes per species (K)",
                             "log10 relative size error, %");
    Canvas framed(png.width(), png.height() + 28);
    framed.paste(png, 0, 28);
    framed.text(10, 20, "Mean size error: blue unscaled, green unscaled by crown area, red scaled to height; dot: chosen K", 13, {0.2f, 0.2f, 0.2f});
    framed.writePng(at("error_vs_k.png"));
    std::ostringstream md;
    md << "# Approximate instancing of `" << run.scene << "`\n\n"
       << summary.plants << " plants (" << scene.canopy.size() << " canopy, " << scene.undergrowth.size() << " undergrowth) as instances of "
       << summary.prototypes << " prototypes: at most " << run.params.prototypesPerSpecies << " per species, by weighted k-means in (log height, "
       << "log crown radius) (Deussen et al. 1998, section 6), weights " << (run.params.weightByCrownArea ? "crown area" : "1") << ", seed "
       << run.params.seed << ".\n\nRelative size error of each plant's instance: **unscaled** (the prototype placed as it is: the larger of its "
       << "height's and crown radius' relative errors) mean " << formatNumber(100 * r.error.meanUnscaled, 3) << " %, max "
       << formatNumber(100 * r.error.maxUnscaled, 3) << " %; **scaled** to the plant's height (the instance table's `scale`: the height exact, "
       << "the crown radius off by the shape difference) mean " << formatNumber(100 * r.error.meanScaled, 3) << " %, max "
       << formatNumber(100 * r.error.maxScaled, 3) << " %. Weighted by crown area (the error as the picture shows it; tiny seedlings "
       << "weigh nothing): unscaled " << formatNumber(100 * r.error.areaMeanUnscaled, 3) << " %, scaled " << formatNumber(100 * r.error.areaMeanScaled, 3)
       << " %.\n\n## By species\n\n| species | plants | prototypes | mean unscaled | max unscaled | mean scaled | max scaled | area-weighted unscaled |\n|---|---:|---:|---:|---:|---:|---:|---:|\n";
    for (std::size_t s = 0; s < biome.species.size(); ++s) {
        std::size_t n = 0, k = 0;
        for (const Prototype& p : r.prototypes)
            if (static_cast<std::size_t>(p.speciesId) == s) {
                n += p.count;
                ++k;
            }
        if (n == 0) continue;
        const InstancingError& e = r.errorBySpecies[s];
        md << "| " << biome.species[s].name << " | " << n << " | " << k << " | " << formatNumber(100 * e.meanUnscaled, 3) << " % | "
           << formatNumber(100 * e.maxUnscaled, 3) << " % | " << formatNumber(100 * e.meanScaled, 3) << " % | " << formatNumber(100 * e.maxScaled, 3) << " % | "
           << formatNumber(100 * e.areaMeanUnscaled, 3) << " % |\n";
    }
    md << "\n## Error against K\n\n" << curve.str() << "\n![error against K](error_vs_k.png)\n\n"
       << "Files: `prototypes.csv` (prototype, species, height, crown radius, instances), `instances.csv` (layer, prototype, species, "
       << "position, rotation about the vertical, uniform scale, id, species name, height, crown radius), in the order of the "
       << "scene's plants, canopy first; `instances.ply` (the same plants as a binary PLY point cloud); `grass.exr`, "
       << "`litter.exr`, `grass.tif`, `litter.tif` (forest floor densities), `terrain.exr` (elevation). docs/export.md has a Blender recipe.\n";
    writeTextFile(at("instancing.md"), md.str());
    outputs.commit();
    step();
    summary.files = {at("instancing.md"), at("prototypes.csv"), at("instances.csv"), at("instances.ply"), at("error_vs_k.png")};
    for (const char* name : {"grass.exr", "litter.exr", "terrain.exr", "grass.tif", "litter.tif"})
        if (fs::exists(at(name))) summary.files.push_back(at(name));
    summary.text = curve.str();
    return summary;
}

}  // namespace eco::synth
