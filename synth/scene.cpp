#include "scene.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>

#include "atomic_file.h"
#include "chart.h"
#include "eco_version.h"
#include "error.h"
#include "h5io.h"
#include "image_out.h"
#include "provenance.h"
#include "text_format.h"

namespace eco::synth {

namespace {

std::string num(double v, int precision = 10) { return formatNumber(v, precision); }

}  // namespace

// ======================================================================== scene file

void writeSceneFile(const std::string& path, const SceneRecord& sc, const Biome& biome, const BiomeDatabase& db) {
    if (!sc.clusterMap.region.sameGeometry(sc.terrainM) || !sc.floor.grass.sameGeometry(sc.terrainM))
        throw ValidationError(path + ": the cluster map, forest floor and terrain of the scene differ in geometry");
    AtomicOutput out(path);
    {
        h5::File f = h5::File::create(out.tempPath());
        f.setAttr("/", "format", std::string(kSceneFormat));
        f.setAttr("/", "schema_version", static_cast<std::int64_t>(kSceneSchemaVersion));
        f.setAttr("/", "code_version", std::string(ECO_VERSION_STRING));
        // The seed's 64 bits, as an int64 attribute (as the database stores seeds).
        f.setAttr("/", "seed", static_cast<std::int64_t>(sc.params.seed));
        for (const h5::NamedAttr& a : sc.params.asAttributes())
            if (a.name != "seed") f.setAttr("/", a);
        for (const h5::NamedAttr& a : sc.floorParams.asAttributes()) f.setAttr("/", a);
        if (sc.params.method == SynthMethod::Deussen)
            f.setAttr("/", "deussen_density_image", sc.densityImageSource.empty() ? std::string("none (the database's density map)")
                                                                                   : sc.densityImageSource);
        if (sc.params.method == SynthMethod::Xu2015) f.setAttr("/", "xu_exemplar", sc.exemplarSource);
        f.setAttrBool("/", "refined", sc.refined);
        if (sc.refined)
            for (const h5::NamedAttr& a : sc.refineParams.asAttributes()) f.setAttr("/", a);
        f.setAttr("/", "database_path", sc.databasePath);
        f.setAttr("/", "database_code_version", sc.databaseCodeVersion.empty() ? db.codeVersion : sc.databaseCodeVersion);
        f.setAttr("/", "database_seeding_radius_factor", db.seedingRadiusFactor);
        f.setAttr("/", "terrain_source", sc.terrainSource);
        f.setAttr("/", "canopy_source", sc.canopySource);
        f.setAttr("/", "abiotics_source", sc.abioticsSource);
        f.setAttr("/", "biome_name", biome.name);
        f.setAttr("/", "biome_toml", db.biomeToml.empty() ? biomeToToml(biome) : db.biomeToml);
        f.setAttr("/", "units", std::string("metres (x east, y north, world coordinates); densities unitless in [0, 1]"));

        writePlants(f, "/canopy", sc.canopy, biome);
        f.setAttr("/canopy", "layer", std::string("canopy"));
        writePlants(f, "/undergrowth", sc.undergrowth, biome);
        out.midWritePoint();
        f.setAttr("/undergrowth", "layer", std::string("undergrowth"));

        f.ensureGroup("/forest_floor");
        f.writeGrid("/forest_floor/grass", sc.floor.grass, "1");
        f.setAttr("/forest_floor/grass", "long_name", std::string("grass density, 0..1"));
        f.writeGrid("/forest_floor/litter", sc.floor.litter, "1");
        f.setAttr("/forest_floor/litter", "long_name", std::string("litter density, 0..1"));
        f.writeGridI32("/cluster_map", sc.clusterMap.region, "1");
        f.setAttr("/cluster_map", "long_name", std::string("database region index, -1 none"));
        f.writeGridI32("/combination_map", sc.clusterMap.combination, "1");
        f.setAttr("/combination_map", "long_name", std::string("sub-biome bitmask (bit b-1 = sub-biome b), 0 none"));
        f.ensureGroup("/terrain");
        f.writeGrid("/terrain/elevation", sc.terrainM, "m");

        // Per database region: what was asked and what was placed.
        const auto& regs = sc.sampling.regions;
        const hsize_t n = regs.size();
        std::vector<std::int32_t> region(n), combination(n), cluster(n);
        std::vector<double> cells(n), area(n), targetDensity(n), targetCount(n), placed(n), density(n);
        for (std::size_t i = 0; i < regs.size(); ++i) {
            const auto& r = regs[i];
            region[i] = r.region;
            combination[i] = db.regions[static_cast<std::size_t>(r.region)].combination;
            cluster[i] = db.regions[static_cast<std::size_t>(r.region)].cluster;
            cells[i] = static_cast<double>(r.cells);
            area[i] = r.areaM2;
            targetDensity[i] = r.targetDensityPerM2;
            targetCount[i] = static_cast<double>(r.targetCount);
            placed[i] = static_cast<double>(r.placed);
            density[i] = r.areaM2 > 0 ? static_cast<double>(r.placed) / r.areaM2 : 0.0;
        }
        f.ensureGroup("/regions");
        f.setAttr("/regions", "count", static_cast<std::int64_t>(n));
        f.setAttr("/regions", "passes", static_cast<std::int64_t>(sc.sampling.passes));
        f.setAttr("/regions", "darts", static_cast<std::int64_t>(sc.sampling.darts));
        f.setAttr("/regions", "darts_on_trunks", static_cast<std::int64_t>(sc.sampling.dartsOnTrunks));
        f.writeI32("/regions/region", region, {n}, "1");
        f.writeI32("/regions/combination", combination, {n}, "1");
        f.writeI32("/regions/cluster", cluster, {n}, "1");
        f.writeF64("/regions/cells", cells, {n}, "1");
        f.writeF64("/regions/area_m2", area, {n}, "m2");
        f.writeF64("/regions/target_density_per_m2", targetDensity, {n}, "m-2");
        f.writeF64("/regions/target_count", targetCount, {n}, "1");
        f.writeF64("/regions/placed", placed, {n}, "1");
        f.writeF64("/regions/density_per_m2", density, {n}, "m-2");
        f.setAttr("/regions", "method", std::string(toString(sc.params.method)));
        if (sc.sampling.structure.size() == regs.size()) {
            // The structured sampler's fitted model of each region (docs/synth.md 2a).
            std::vector<std::int32_t> scales(n);
            std::vector<double> sigma(2 * n), kappa(2 * n), amplitude(2 * n), fitRms(n), contextRms(n);
            for (std::size_t i = 0; i < regs.size(); ++i) {
                const RegionStructure& st = sc.sampling.structure[i];
                scales[i] = st.scales;
                for (int k = 0; k < 2; ++k) {
                    sigma[2 * i + static_cast<std::size_t>(k)] = st.sigmaM[k];
                    kappa[2 * i + static_cast<std::size_t>(k)] = st.parentsPerM2[k];
                    amplitude[2 * i + static_cast<std::size_t>(k)] = st.pooledAmplitude[k];
                }
                fitRms[i] = st.pooledFitRms;
                contextRms[i] = st.pooledContextRms;
            }
            f.writeI32("/regions/cluster_fields", scales, {n}, "1");
            f.writeF64("/regions/cluster_sigma_m", sigma, {n, 2}, "m");
            f.writeF64("/regions/cluster_parents_per_m2", kappa, {n, 2}, "m-2");
            f.writeF64("/regions/cluster_pooled_amplitude", amplitude, {n, 2}, "1");
            f.writeF64("/regions/pooled_g_fit_rms", fitRms, {n}, "1");
            f.writeF64("/regions/pooled_g_context_only_rms", contextRms, {n}, "1");
            f.setAttr("/regions", "heights_limited_by_crown", static_cast<std::int64_t>(sc.sampling.heightsLimitedByCrown));
            f.setAttr("/regions", "darts_inhibited", static_cast<std::int64_t>(sc.sampling.dartsInhibited));
        }

        if (sc.params.method == SynthMethod::Deussen && !sc.sampling.deussen.empty()) {
            // The Deussen sampler's record of each species, in placement order (docs/synth.md 2c).
            const std::size_t m = sc.sampling.deussen.size();
            std::vector<std::int32_t> species(m);
            std::vector<double> cell(m), minDist(m), dots(m), dropped(m), ceBefore(m), ceAfter(m);
            for (std::size_t i = 0; i < m; ++i) {
                const UndergrowthSample::DeussenSpecies& d = sc.sampling.deussen[i];
                species[i] = d.species;
                cell[i] = d.halftoneCellM;
                minDist[i] = d.minDistanceM;
                dots[i] = static_cast<double>(d.dots);
                dropped[i] = static_cast<double>(d.dropped);
                ceBefore[i] = d.clarkEvansBefore;
                ceAfter[i] = d.clarkEvansAfter;
            }
            f.writeI32("/regions/deussen_species_order", species, {m}, "1");
            f.writeF64("/regions/deussen_halftone_cell_m", cell, {m}, "m");
            f.writeF64("/regions/deussen_min_distance_m", minDist, {m}, "m");
            f.writeF64("/regions/deussen_dots", dots, {m}, "1");
            f.writeF64("/regions/deussen_dropped", dropped, {m}, "1");
            f.writeF64("/regions/deussen_clark_evans_before", ceBefore, {m}, "1");
            f.writeF64("/regions/deussen_clark_evans_after", ceAfter, {m}, "1");
            f.setAttr("/regions", "heights_limited_by_crown", static_cast<std::int64_t>(sc.sampling.heightsLimitedByCrown));
            f.setAttr("/regions", "darts_inhibited", static_cast<std::int64_t>(sc.sampling.dartsInhibited));
        }

        if (sc.params.method == SynthMethod::Xu2015) {
            // The Xu 2015 sampler's record (docs/synth.md 2d).
            const XuPattern& x = sc.sampling.xu;
            f.setAttr("/regions", "xu_radius_m", x.radiusM);
            f.setAttr("/regions", "xu_min_distance_m", x.minDistanceM);
            f.setAttr("/regions", "xu_interior_candidates", x.interiorCandidates);
            f.setAttr("/regions", "xu_extensions", x.extensions);
            f.setAttr("/regions", "xu_hole_seeds", x.holeSeeds);
            f.setAttr("/regions", "xu_conflicts", x.conflicts);
            f.setAttr("/regions", "xu_seam_drops", x.seamDrops);
            f.setAttr("/regions", "xu_tiles", static_cast<std::int64_t>(x.tiles));
            f.setAttr("/regions", "xu_dropped_outside_region", sc.sampling.xuDroppedOutsideRegion);
            f.setAttr("/regions", "xu_dropped_on_trunk", sc.sampling.xuDroppedOnTrunk);
            f.setAttr("/regions", "heights_limited_by_crown", static_cast<std::int64_t>(sc.sampling.heightsLimitedByCrown));
        }

        f.ensureGroup("/refinement");
        f.setAttrBool("/refinement", "applied", sc.refined);
        if (sc.refined) {
            const RefineResult& rr = sc.refineResult;
            f.setAttr("/refinement", "pcf_distance_before", rr.distanceBefore);
            f.setAttr("/refinement", "pcf_distance_after", rr.distanceAfter);
            f.setAttr("/refinement", "proposals", static_cast<std::int64_t>(rr.proposals));
            f.setAttr("/refinement", "accepted", static_cast<std::int64_t>(rr.accepted));
            f.setAttr("/refinement", "rmax_m", rr.rMaxM);
            f.writeF64("/refinement/objective_per_sweep", rr.objectivePerSweep, {rr.objectivePerSweep.size()}, "1");
        }

        // Dates and wall times: measured, not computed (docs/hdf5.md), so kept apart.
        std::vector<ProvenanceEntry> prov{{"created_utc", utcTimestamp()}, {"sampling_seconds", sc.sampling.seconds}};
        if (sc.refined) prov.push_back({"refinement_seconds", sc.refineResult.seconds});
        const std::string dbCreated = sc.databaseCreatedUtc.empty() ? db.createdUtc : sc.databaseCreatedUtc;
        if (!dbCreated.empty()) prov.push_back({"database_created_utc", dbCreated});
        writeProvenance(f, prov);
    }
    out.commit();
}

SceneData readSceneFile(const std::string& path, const Biome& biome) {
    h5::File f = h5::File::openRead(path);
    if (!f.hasAttr("/", "format") || f.attrString("/", "format") != kSceneFormat)
        throw IoError(path + ": not an eco-scene file (root attribute format is not \"" + kSceneFormat + "\")");
    const std::int64_t version = f.hasAttr("/", "schema_version") ? f.attrInt("/", "schema_version") : -1;
    if (version != kSceneSchemaVersion)
        throw IoError(path + ": scene schema_version " + std::to_string(version) + ", this eco reads version " +
                      std::to_string(kSceneSchemaVersion));
    SceneData d;
    d.canopy = readPlants(f, "/canopy", biome);
    d.undergrowth = readPlants(f, "/undergrowth", biome);
    d.clusterMap = f.readGridI32("/cluster_map");
    d.combinationMap = f.readGridI32("/combination_map");
    d.terrainM = f.readGrid("/terrain/elevation");
    d.grass = f.readGrid("/forest_floor/grass");
    d.litter = f.readGrid("/forest_floor/litter");
    if (!d.clusterMap.sameGeometry(d.terrainM) || !d.grass.sameGeometry(d.terrainM))
        throw IoError(path + ": /cluster_map, /forest_floor and /terrain/elevation differ in geometry");
    d.seed = static_cast<std::uint64_t>(f.attrInt("/", "seed"));
    d.databasePath = f.hasAttr("/", "database_path") ? f.attrString("/", "database_path") : "";
    d.biomeName = f.hasAttr("/", "biome_name") ? f.attrString("/", "biome_name") : "";
    return d;
}

void writeScenePlantsCsv(const std::string& path, const std::vector<Plant>& canopy,
                         const std::vector<Plant>& undergrowth, const Biome& biome) {
    writePlantLayersCsv(path, {{"canopy", &canopy}, {"undergrowth", &undergrowth}}, biome);
}

// ======================================================================== PDB

namespace {
/// A length in metres as fixed-point text with at least 4 decimals and at least 4 significant
/// digits: "33.2550", "0.2500", "0.01234", "0.0000002294". Values from 0.1 m up print as the
/// earlier "%.4f"; a seedling of 0.2 micrometres no longer prints as 0.0000. Always
/// fixed-point (no exponent, one token), so readers that scan "%f" tokens read it unchanged.
std::string pdbLength(double metres) {
    int decimals = 4;
    if (metres != 0 && std::isfinite(metres))
        decimals = std::max(4, 3 - static_cast<int>(std::floor(std::log10(std::fabs(metres)))));
    decimals = std::min(decimals, 12);
    char text[64];
    std::snprintf(text, sizeof text, "%.*f", decimals, metres);
    return text;
}
}  // namespace

void writePdb(const std::string& path, const std::vector<Plant>& canopy, const std::vector<Plant>& undergrowth) {
    std::map<int, PdbSpecies> bySpecies;
    for (const auto* list : {&canopy, &undergrowth})
        for (const Plant& p : *list) {
            PdbSpecies& s = bySpecies[p.speciesId];
            s.speciesId = p.speciesId;
            s.plants.push_back(p);
        }
    AtomicOutput out(path);
    {
        std::FILE* f = std::fopen(out.tempPath().c_str(), "w");
        if (!f) throw IoError(path + ": cannot write PDB plant list");
        std::fprintf(f, "%zu\n", bySpecies.size());
        for (auto& [id, s] : bySpecies) {
            double lo = std::numeric_limits<double>::infinity(), hi = 0, ratio = 0;
            std::size_t nRatio = 0;
            for (const Plant& p : s.plants) {
                lo = std::min(lo, p.heightM);
                hi = std::max(hi, p.heightM);
                if (p.heightM > 0) {
                    ratio += p.crownRadiusM / p.heightM;
                    ++nRatio;
                }
            }
            std::fprintf(f, "%d %s %s %.6f\n%zu\n", id, pdbLength(lo).c_str(), pdbLength(hi).c_str(),
                         nRatio ? ratio / static_cast<double>(nRatio) : 0.0, s.plants.size());
            for (const Plant& p : s.plants)
                std::fprintf(f, "%.4f %.4f %.4f %s %s\n", p.xM, p.yM, p.groundZM, pdbLength(p.heightM).c_str(),
                             pdbLength(p.crownRadiusM).c_str());
        }
        if (std::fclose(f) != 0) throw IoError(path + ": error while writing the PDB plant list");
    }
    out.commit();
}

std::vector<PdbSpecies> readPdb(const std::string& path) {
    std::ifstream in(path);
    if (!in) throw IoError(path + ": cannot open PDB plant list");
    int line = 0;
    std::string text;
    auto next = [&](const char* what) {
        while (std::getline(in, text)) {
            ++line;
            if (text.find_first_not_of(" \t\r") != std::string::npos) return;
        }
        throw IoError(path + ":" + std::to_string(line) + ": file ends where " + what + " was expected");
    };
    auto fail = [&](const std::string& what) {
        throw IoError(path + ":" + std::to_string(line) + ": " + what + " (line: '" + text + "')");
    };
    next("the number of species");
    long nSpecies = -1;
    {
        std::istringstream ss(text);
        if (!(ss >> nSpecies) || nSpecies < 0) fail("expected the number of species");
    }
    std::vector<PdbSpecies> out;
    for (long s = 0; s < nSpecies; ++s) {
        PdbSpecies sp;
        next("a species line (id min_height max_height radius_ratio)");
        {
            std::istringstream ss(text);
            if (!(ss >> sp.speciesId >> sp.minHeightM >> sp.maxHeightM >> sp.meanRadiusToHeight))
                fail("expected 'species_id min_height max_height mean_radius_to_height_ratio'");
        }
        next("a plant count");
        long n = -1;
        {
            std::istringstream ss(text);
            if (!(ss >> n) || n < 0) fail("expected the number of plants of species " + std::to_string(sp.speciesId));
        }
        // The count comes from the file: reserve no more than a small file could hold, so that
        // a damaged count (1e14) ends in "file ends" below, not in a huge allocation.
        sp.plants.reserve(static_cast<std::size_t>(std::min<long>(n, 4096)));
        for (long i = 0; i < n; ++i) {
            next("a plant line (x y z height crown_radius)");
            Plant p;
            p.speciesId = sp.speciesId;
            std::istringstream ss(text);
            if (!(ss >> p.xM >> p.yM >> p.groundZM >> p.heightM >> p.crownRadiusM) || !std::isfinite(p.xM) ||
                !std::isfinite(p.yM) || !std::isfinite(p.groundZM) || !std::isfinite(p.heightM) ||
                !std::isfinite(p.crownRadiusM))
                fail("expected five finite numbers 'x y z height crown_radius'");
            sp.plants.push_back(p);
        }
        out.push_back(std::move(sp));
    }
    return out;
}

// ======================================================================== pictures

RectWindow defaultZoomWindow(const Grid<float>& terrainM, double sideM) {
    const double side = std::min({sideM, terrainM.extentX(), terrainM.extentY()});
    const double cx = terrainM.originX() + 0.5 * terrainM.extentX();
    const double cy = terrainM.originY() + 0.5 * terrainM.extentY();
    return RectWindow{cx - 0.5 * side, cy - 0.5 * side, cx + 0.5 * side, cy + 0.5 * side};
}

void writeScenePng(const std::string& path, const std::vector<Plant>& canopy, const std::vector<Plant>& undergrowth,
                   const Grid<float>& terrainM, const ForestFloor* floor, const Biome& biome, const std::string& title,
                   const RectWindow* crop, int maxSidePx) {
    if (terrainM.empty()) throw ValidationError(path + ": cannot draw on an empty terrain");
    RectWindow view{terrainM.originX(), terrainM.originY(), terrainM.originX() + terrainM.extentX(),
                    terrainM.originY() + terrainM.extentY()};
    if (crop) {
        crop->validate(path + ": picture window");
        view = *crop;
    }
    const double pxPerM = maxSidePx / std::max(view.widthM(), view.heightM());
    const int pw = std::max(1, static_cast<int>(std::lround(view.widthM() * pxPerM)));
    const int ph = std::max(1, static_cast<int>(std::lround(view.heightM() * pxPerM)));
    Canvas picture(pw, ph);
    const Grid<float> shade = hillshade(terrainM);
    const bool withFloor = floor && floor->grass.sameGeometry(terrainM) && floor->litter.sameGeometry(terrainM);
    for (int py = 0; py < ph; ++py)
        for (int px = 0; px < pw; ++px) {
            const double x = view.x0 + (px + 0.5) / pxPerM, y = view.y1 - (py + 0.5) / pxPerM;  // row 0 = north
            const int ix = std::clamp(terrainM.cellX(x), 0, terrainM.width() - 1);
            const int iy = std::clamp(terrainM.cellY(y), 0, terrainM.height() - 1);
            const float s = shade(ix, iy);
            const float g = 0.45f + 0.45f * s;
            Rgb c = {g, g, g};
            if (withFloor) {
                const float grass = floor->grass(ix, iy), litter = floor->litter(ix, iy);
                const Rgb green = {0.55f * g, 0.80f * g, 0.35f * g}, brown = {0.55f * g, 0.42f * g, 0.25f * g};
                for (int k = 0; k < 3; ++k) {
                    c[static_cast<std::size_t>(k)] += 0.8f * grass * (green[static_cast<std::size_t>(k)] - c[static_cast<std::size_t>(k)]);
                    c[static_cast<std::size_t>(k)] += 0.6f * litter * (brown[static_cast<std::size_t>(k)] - c[static_cast<std::size_t>(k)]);
                }
            }
            picture.set(px, py, c);
        }
    auto toPx = [&](double x, double y, double& ox, double& oy) {
        ox = (x - view.x0) * pxPerM;
        oy = (view.y1 - y) * pxPerM;
    };
    auto visible = [&](const Plant& p) {
        return p.xM + p.crownRadiusM >= view.x0 && p.xM - p.crownRadiusM <= view.x1 && p.yM + p.crownRadiusM >= view.y0 &&
               p.yM - p.crownRadiusM <= view.y1;
    };
    const std::size_t nS = biome.species.size();
    std::vector<std::size_t> uCount(nS, 0), cCount(nS, 0);
    // Undergrowth, shortest first so that taller shrubs lie on top.
    std::vector<const Plant*> under;
    for (const Plant& p : undergrowth)
        if (visible(p)) under.push_back(&p);
    std::stable_sort(under.begin(), under.end(), [](const Plant* a, const Plant* b) { return a->heightM < b->heightM; });
    for (const Plant* p : under) {
        double x, y;
        toPx(p->xM, p->yM, x, y);
        const Rgb c = categoryColour(p->speciesId);
        picture.fillDisc(x, y, p->crownRadiusM * pxPerM, c, 0.9f);
        ++uCount[static_cast<std::size_t>(p->speciesId)];
    }
    const bool outlines = pxPerM >= 3.0;  // crown rims only where crowns are big enough to read
    for (const Plant& p : canopy) {
        if (!visible(p)) continue;
        double x, y;
        toPx(p.xM, p.yM, x, y);
        const Rgb c = categoryColour(p.speciesId);
        const double r = p.crownRadiusM * pxPerM;
        picture.fillDisc(x, y, r, c, 0.35f);
        if (outlines) {
            const Rgb rim = {0.6f * c[0], 0.6f * c[1], 0.6f * c[2]};
            const int segments = std::clamp(static_cast<int>(r), 16, 128);
            for (int k = 0; k < segments; ++k) {
                const double a0 = 6.283185307179586 * k / segments, a1 = 6.283185307179586 * (k + 1) / segments;
                picture.drawLine(x + r * std::cos(a0), y + r * std::sin(a0), x + r * std::cos(a1), y + r * std::sin(a1), rim);
            }
        }
        picture.fillDisc(x, y, std::max(1.0, 0.25 * pxPerM), {0.15f, 0.10f, 0.05f});
        ++cCount[static_cast<std::size_t>(p.speciesId)];
    }
    std::vector<std::pair<std::string, Rgb>> entries;
    std::size_t totalU = 0, totalC = 0;
    for (std::size_t s = 0; s < nS; ++s) {
        totalU += uCount[s];
        totalC += cCount[s];
        if (uCount[s] == 0 && cCount[s] == 0) continue;
        std::string label = biome.species[s].name + ":";
        if (uCount[s]) label += " " + std::to_string(uCount[s]) + " undergrowth";
        if (cCount[s]) label += std::string(uCount[s] ? "," : "") + " " + std::to_string(cCount[s]) + " canopy";
        entries.emplace_back(label, categoryColour(static_cast<int>(s)));
    }
    if (withFloor) {
        entries.emplace_back("ground: grass (green)", Rgb{0.5f, 0.72f, 0.32f});
        entries.emplace_back("ground: litter (brown)", Rgb{0.5f, 0.38f, 0.22f});
    }
    entries.emplace_back("canopy: translucent crowns, dark trunks", Rgb{0.15f, 0.10f, 0.05f});
    char scale[96];
    std::snprintf(scale, sizeof scale, "%.0f x %.0f m", view.widthM(), view.heightM());
    entries.emplace_back(scale, Rgb{1.f, 1.f, 1.f});
    const std::string heading =
        title + " (" + std::to_string(totalC) + " canopy, " + std::to_string(totalU) + " undergrowth)";
    const MapExtent world{view.x0, view.y1 - ph / pxPerM, view.x0 + pw / pxPerM, view.y1};
    withLegend(mapFrame(picture, world).canvas, heading, entries).writePng(path);
}

// ======================================================================== comparison

std::vector<double> pooledUndergrowthG(const DbRegion& r, const BiomeDatabase& db) {
    const int nS = db.speciesCount();
    const int nb = db.pcfBins.count;
    std::vector<double> sum(static_cast<std::size_t>(nb), 0.0);
    double norm = 0;
    for (const DbPairStats& p : r.pairs) {
        if (p.source >= nS || p.target >= nS) continue;
        norm += p.normalisation;
        for (int k = 0; k < nb && static_cast<std::size_t>(k) < p.translateWeighted.size(); ++k)
            sum[static_cast<std::size_t>(k)] += p.translateWeighted[static_cast<std::size_t>(k)];
    }
    std::vector<double> g(static_cast<std::size_t>(nb), 0.0);
    for (int k = 0; k < nb; ++k) g[static_cast<std::size_t>(k)] = annulusPcf(sum[static_cast<std::size_t>(k)], db.pcfBins.annulusAreaM2(k), norm);
    return g;
}

std::vector<double> pooledUndergrowthG(const ScenePairStats& s, int region, int nSpecies) {
    const auto& R = s.regions.at(static_cast<std::size_t>(region));
    const int nb = s.bins.count, C = s.nCategories;
    std::vector<double> g(static_cast<std::size_t>(nb), 0.0);
    if (R.count.empty() || !(R.areaM2 > 0)) return g;
    double norm = 0;
    for (int i = 0; i < nSpecies; ++i)
        for (int j = 0; j < nSpecies; ++j)
            norm += pairNormalisation(static_cast<double>(R.count[static_cast<std::size_t>(i)]),
                                      static_cast<double>(R.count[static_cast<std::size_t>(j)]), i == j, R.areaM2);
    for (int k = 0; k < nb; ++k) {
        double sum = 0;
        for (int i = 0; i < nSpecies; ++i)
            for (int j = 0; j < nSpecies; ++j)
                sum += R.weighted[(static_cast<std::size_t>(i) * static_cast<std::size_t>(C) + static_cast<std::size_t>(j)) *
                                      static_cast<std::size_t>(nb) +
                                  static_cast<std::size_t>(k)];
        g[static_cast<std::size_t>(k)] = annulusPcf(sum, s.bins.annulusAreaM2(k), norm);
    }
    return g;
}

namespace {

/// Total-variation distance between a sample binned on a database histogram's edges and
/// that histogram (overflow as one more bin); -1 when either is empty.
double histogramTv(const DbHistogram& target, const std::vector<double>& values) {
    const std::size_t nb = target.counts.size();
    if (nb == 0 || values.empty()) return -1;
    std::vector<double> mine(nb + 1, 0.0);
    for (double v : values) {
        const auto it = std::upper_bound(target.edges.begin(), target.edges.end(), v);
        std::size_t k = it == target.edges.begin() ? 0 : static_cast<std::size_t>(it - target.edges.begin()) - 1;
        if (v == target.edges.back()) k = nb - 1;  // the last bin includes its upper edge
        mine[std::min(k, nb)] += 1;
    }
    double tTotal = target.overflow;
    for (double c : target.counts) tTotal += c;
    if (!(tTotal > 0)) return -1;
    double tv = 0;
    for (std::size_t k = 0; k <= nb; ++k) {
        const double t = (k < nb ? target.counts[k] : target.overflow) / tTotal;
        tv += std::abs(mine[k] / static_cast<double>(values.size()) - t);
    }
    return 0.5 * tv;
}

}  // namespace

SceneComparison compareScene(const std::vector<Plant>& canopy, const std::vector<Plant>& undergrowth,
                             const Grid<std::int32_t>& clusterMap, const BiomeDatabase& db, const RectWindow* window,
                             std::size_t maxSourcesPerRegion) {
    const int nR = static_cast<int>(db.regions.size());
    const int nS = db.speciesCount();
    for (std::int32_t r : clusterMap.data())
        if (r >= nR)
            throw ValidationError("scene comparison: the scene's cluster map names region " + std::to_string(r) +
                                  " but the database has " + std::to_string(nR) + " regions; was it synthesized from "
                                  "another database?");
    Grid<std::int32_t> labels = clusterMap;
    if (window)
        for (int iy = 0; iy < labels.height(); ++iy)
            for (int ix = 0; ix < labels.width(); ++ix)
                if (!window->contains(labels.cellCentreX(ix), labels.cellCentreY(iy))) labels(ix, iy) = -1;
    SceneComparison c;
    c.regions.resize(static_cast<std::size_t>(nR));
    for (int r = 0; r < nR; ++r) {
        RegionComparison& rc = c.regions[static_cast<std::size_t>(r)];
        const DbRegion& dr = db.regions[static_cast<std::size_t>(r)];
        rc.region = r;
        rc.name = db.combinationName(dr.combination) + " / cluster " + std::to_string(dr.cluster);
        rc.targetDensityPerM2 = dr.densityPerM2;
        rc.proportion.assign(static_cast<std::size_t>(nS), 0.0);
    }
    for (std::int32_t r : labels.data())
        if (r >= 0) ++c.regions[static_cast<std::size_t>(r)].cells;
    const double cellArea = labels.cellSizeM() * labels.cellSizeM();
    // Plants per region and species, and their sizes.
    std::vector<std::vector<std::vector<double>>> heights(static_cast<std::size_t>(nR)), radii(static_cast<std::size_t>(nR));
    for (int r = 0; r < nR; ++r) {
        heights[static_cast<std::size_t>(r)].resize(static_cast<std::size_t>(nS));
        radii[static_cast<std::size_t>(r)].resize(static_cast<std::size_t>(nS));
    }
    for (const Plant& p : undergrowth) {
        const int ix = labels.cellX(p.xM), iy = labels.cellY(p.yM);
        if (!labels.inside(ix, iy) || (window && !window->contains(p.xM, p.yM))) continue;
        const int r = labels(ix, iy);
        if (r < 0 || p.speciesId < 0 || p.speciesId >= nS) continue;
        ++c.regions[static_cast<std::size_t>(r)].plants;
        heights[static_cast<std::size_t>(r)][static_cast<std::size_t>(p.speciesId)].push_back(p.heightM);
        radii[static_cast<std::size_t>(r)][static_cast<std::size_t>(p.speciesId)].push_back(p.crownRadiusM);
    }
    c.pairs = scenePairStatistics(canopy, undergrowth, labels, nR, nS, db.pcfBins, window, maxSourcesPerRegion);
    const PcfDistance pd = pcfDistance(c.pairs, db);
    c.pcfDistance = pd.overall;
    for (int r = 0; r < nR; ++r) {
        RegionComparison& rc = c.regions[static_cast<std::size_t>(r)];
        const DbRegion& dr = db.regions[static_cast<std::size_t>(r)];
        rc.areaM2 = static_cast<double>(rc.cells) * cellArea;
        rc.densityPerM2 = rc.areaM2 > 0 ? static_cast<double>(rc.plants) / rc.areaM2 : 0.0;
        rc.densityRelativeError = rc.targetDensityPerM2 > 0 ? rc.densityPerM2 / rc.targetDensityPerM2 - 1.0 : 0.0;
        double wH = 0, wR = 0;
        for (int s = 0; s < nS; ++s) {
            const std::size_t si = static_cast<std::size_t>(s);
            const double n = static_cast<double>(heights[static_cast<std::size_t>(r)][si].size());
            rc.proportion[si] = rc.plants > 0 ? n / static_cast<double>(rc.plants) : 0.0;
            const double target = si < dr.speciesProportion.size() ? dr.speciesProportion[si] : 0.0;
            if (rc.plants > 0) rc.proportionMaxDifference = std::max(rc.proportionMaxDifference, std::abs(rc.proportion[si] - target));
            if (n > 0 && si < dr.height.size()) {
                const double th = histogramTv(dr.height[si], heights[static_cast<std::size_t>(r)][si]);
                if (th >= 0) {
                    rc.heightDistance += n * th;
                    wH += n;
                }
                const double tr = histogramTv(dr.crownRadius[si], radii[static_cast<std::size_t>(r)][si]);
                if (tr >= 0) {
                    rc.radiusDistance += n * tr;
                    wR += n;
                }
            }
        }
        if (wH > 0) rc.heightDistance /= wH;
        if (wR > 0) rc.radiusDistance /= wR;
        rc.pcfDistance = pd.perRegion[static_cast<std::size_t>(r)];
    }
    return c;
}

std::string comparisonTable(const SceneComparison& c, const BiomeDatabase& db) {
    std::ostringstream os;
    os << "| region | combination / cluster | area m2 | plants | density /m2 | target /m2 | rel. error | "
          "max share diff | height TV | radius TV | g distance |\n"
       << "|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n";
    char line[512];
    for (const auto& r : c.regions) {
        if (r.cells == 0) continue;
        std::snprintf(line, sizeof line, "| %d | %s | %.0f | %lld | %.4f | %.4f | %+.2f %% | %.4f | %.4f | %.4f | %.4f |\n",
                      r.region, r.name.c_str(), r.areaM2, static_cast<long long>(r.plants), r.densityPerM2,
                      r.targetDensityPerM2, 100.0 * r.densityRelativeError, r.proportionMaxDifference, r.heightDistance,
                      r.radiusDistance, r.pcfDistance);
        os << line;
    }
    std::snprintf(line, sizeof line,
                  "\npair-correlation distance over all regions: %.4f (RMS difference of g over %d bins to %.3g m, "
                  "weighted by point pairs; 0 = identical)\n",
                  c.pcfDistance, db.pcfBins.count, db.pcfBins.rMaxM);
    os << line;
    return os.str();
}

void writeComparisonPng(const std::string& path, const SceneComparison& c, const BiomeDatabase& db) {
    std::vector<const RegionComparison*> shown;
    for (const auto& r : c.regions)
        if (r.cells > 0) shown.push_back(&r);
    std::stable_sort(shown.begin(), shown.end(), [](const RegionComparison* a, const RegionComparison* b) { return a->areaM2 > b->areaM2; });
    const std::size_t withCells = shown.size();
    const std::size_t maxPanels = 24;
    if (shown.size() > maxPanels) shown.resize(maxPanels);
    const int nS = db.speciesCount();
    const Rgb black = {0.f, 0.f, 0.f}, red = {0.85f, 0.1f, 0.1f}, grey = {0.45f, 0.45f, 0.45f};
    std::vector<double> mids;
    for (int k = 0; k < db.pcfBins.count; ++k) mids.push_back(db.pcfBins.midM(k));
    std::vector<ChartPanel> panels;
    for (const RegionComparison* rc : shown) {
        const std::vector<double> gt = pooledUndergrowthG(db.regions[static_cast<std::size_t>(rc->region)], db);
        const std::vector<double> gs = pooledUndergrowthG(c.pairs, rc->region, nS);
        double gMax = 2.0;
        for (double v : gt) gMax = std::max(gMax, v);
        for (double v : gs) gMax = std::max(gMax, v);
        ChartPanel p;
        char title[200];
        std::snprintf(title, sizeof title, "region %d: %.2f vs %.2f plants/m2", rc->region, rc->densityPerM2,
                      rc->targetDensityPerM2);
        p.title = title;
        p.subtitle = rc->name + ", g distance " + num(rc->pcfDistance, 3);
        p.xmin = 0;
        p.xmax = db.pcfBins.rMaxM;
        p.ymin = 0;
        p.ymax = std::min(gMax, 10.0) * 1.05;  // g above 10 drawn at the top edge
        p.reference = ChartReference{1.0, grey, true};
        p.series.push_back(ChartSeries{"database", mids, gt, black});
        p.series.push_back(ChartSeries{"scene", mids, gs, red});
        panels.push_back(std::move(p));
    }
    ChartPanelsLayout layout;
    layout.title = "g(r) of all undergrowth per region: database vs synthesized scene";
    layout.notes.push_back("pcf distance over all regions " + num(c.pcfDistance, 4) +
                           "; g distance = RMS of g(scene) - g(database) over category pairs and bins, weighted by "
                           "pairs (0 = identical). Panel titles: scene density vs database density.");
    if (withCells > shown.size())
        layout.notes.push_back("The " + std::to_string(shown.size()) + " largest of " + std::to_string(withCells) +
                               " regions in the scene are shown; compare.md lists all.");
    layout.key = {{"database", black}, {"scene", red}, {"g = 1 (no interaction)", grey, true, 1}};
    layout.xlabel = "r (m)";
    layout.ylabel = "g(r)";
    layout.columns = 3;
    chartPanels(panels, layout).writePng(path);
}

}  // namespace eco::synth
