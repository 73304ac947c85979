#include "biome_db.h"

#include "text_format.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <limits>

#include "atomic_file.h"
#include "error.h"
#include "h5io.h"
#include "provenance.h"

namespace eco {

namespace {
/// The units of a dataset with one column per abiotic feature (their units differ): CF has no
/// unit per column, so the attribute points to the list.
const std::string kPerFeatureUnits = "per column: /features/units";
}  // namespace

namespace {

int popcount(unsigned v) {
    int n = 0;
    for (; v; v &= v - 1) ++n;
    return n;
}

std::string regionGroup(std::size_t r) {
    char buf[48];
    std::snprintf(buf, sizeof buf, "/regions/region_%04zu", r);
    return buf;
}

std::string inputGroup(std::size_t i) {
    char buf[48];
    std::snprintf(buf, sizeof buf, "/inputs/input_%03zu", i);
    return buf;
}

hsize_t hs(std::size_t v) { return static_cast<hsize_t>(v); }

/// Rows of equal length flattened, for a [rows][cols] dataset.
template <typename Rows, typename Get>
std::vector<double> flatten(const Rows& rows, std::size_t cols, Get get) {
    std::vector<double> out;
    out.reserve(rows.size() * cols);
    for (const auto& r : rows) {
        const auto& v = get(r);
        for (std::size_t c = 0; c < cols; ++c) out.push_back(c < v.size() ? v[c] : std::numeric_limits<double>::quiet_NaN());
    }
    return out;
}

std::vector<double> featuresRow(const Features& f) { return {f.begin(), f.end()}; }

// ---- reading helpers: every shape is checked, every message names file and dataset ----

class Reader {
public:
    explicit Reader(const h5::File& f) : f_(f) {}

    std::vector<double> f64(const std::string& name, std::vector<std::size_t> expect) const {
        std::vector<hsize_t> dims;
        auto v = f_.readF64(name, &dims);
        check(name, dims, expect);
        return v;
    }
    std::vector<std::int32_t> i32(const std::string& name, std::vector<std::size_t> expect) const {
        std::vector<hsize_t> dims;
        auto v = f_.readI32(name, &dims);
        check(name, dims, expect);
        return v;
    }
    std::vector<std::string> strings(const std::string& name, std::size_t expect) const {
        auto v = f_.readStrings(name);
        if (expect != kAny && v.size() != expect)
            throw IoError(f_.path() + ": " + name + ": expected " + std::to_string(expect) + " entries, found " +
                          std::to_string(v.size()));
        return v;
    }
    /// Length of a 1-D dataset.
    std::size_t length(const std::string& name) const {
        const auto dims = f_.shape(name);
        if (dims.size() != 1) throw IoError(f_.path() + ": " + name + ": expected a 1-D dataset");
        return static_cast<std::size_t>(dims[0]);
    }
    static constexpr std::size_t kAny = static_cast<std::size_t>(-1);

private:
    void check(const std::string& name, const std::vector<hsize_t>& dims, const std::vector<std::size_t>& expect) const {
        bool ok = dims.size() == expect.size();
        for (std::size_t i = 0; ok && i < dims.size(); ++i) ok = expect[i] == kAny || dims[i] == expect[i];
        if (ok) return;
        auto show = [](auto const& d) {
            std::string s = "[";
            for (std::size_t i = 0; i < d.size(); ++i) {
                if (i) s += "][";
                s += d[i] == static_cast<std::decay_t<decltype(d[i])>>(kAny) ? std::string("*") : std::to_string(d[i]);
            }
            return s + "]";
        };
        throw IoError(f_.path() + ": " + name + ": expected shape " + show(expect) + ", found " + show(dims));
    }
    const h5::File& f_;
};

// Row `row` of a [rows][cols] feature table; factors beyond the file's `cols` columns (a file
// written before the factor existed) get `missing`.
Features featuresAt(const std::vector<double>& flat, std::size_t row, std::size_t cols, double missing) {
    Features f{};
    f.fill(missing);
    for (std::size_t c = 0; c < cols; ++c) f[c] = flat[row * cols + c];
    return f;
}

std::vector<double> rowOf(const std::vector<double>& flat, std::size_t row, std::size_t cols) {
    return {flat.begin() + static_cast<std::ptrdiff_t>(row * cols), flat.begin() + static_cast<std::ptrdiff_t>((row + 1) * cols)};
}

}  // namespace

int DbRegion::replicates() const {
    if (inputAreaM2.empty()) return -1;
    return static_cast<int>(std::count_if(inputAreaM2.begin(), inputAreaM2.end(), [](double a) { return a > 0; }));
}

const DbPairStats* DbRegion::pair(int source, int target) const {
    auto it = std::lower_bound(pairs.begin(), pairs.end(), std::make_pair(source, target),
                               [](const DbPairStats& p, const std::pair<int, int>& key) {
                                   return std::make_pair(p.source, p.target) < key;
                               });
    return it != pairs.end() && it->source == source && it->target == target ? &*it : nullptr;
}

std::string BiomeDatabase::categoryName(int category) const {
    const int ns = speciesCount();
    if (category < 0 || category >= 2 * ns) return "category " + std::to_string(category);
    const std::string& name = speciesNames[static_cast<std::size_t>(category % ns)];
    return category >= ns ? name + " (canopy)" : name;
}

std::string BiomeDatabase::combinationName(int mask) const { return eco::combinationName(subBiomeNames, mask); }

std::string combinationName(const std::vector<std::string>& subBiomeNames, int mask) {
    std::string numbers, names;
    for (std::size_t b = 0; b < 31; ++b) {
        if (!(mask & (1 << b))) continue;
        if (!numbers.empty()) {
            numbers += "+";
            names += ", ";
        }
        numbers += std::to_string(b + 1);
        names += b < subBiomeNames.size() ? subBiomeNames[b] : "?";
    }
    return numbers.empty() ? "none" : numbers + " (" + names + ")";
}

int BiomeDatabase::combinationIndex(int mask) const {
    for (std::size_t i = 0; i < combinations.size(); ++i)
        if (combinations[i].mask == mask) return static_cast<int>(i);
    return -1;
}

int BiomeDatabase::standInCombination(int combination) const {
    if (combination <= 0) return -1;
    if (combinationIndex(combination) >= 0) return combination;
    int best = -1, bestShared = 0, bestDiff = 0;
    for (const auto& c : combinations) {  // ascending mask: ties keep the lowest
        const int shared = popcount(static_cast<unsigned>(c.mask & combination));
        const int diff = popcount(static_cast<unsigned>(c.mask ^ combination));
        if (shared == 0) continue;
        if (best < 0 || shared > bestShared || (shared == bestShared && diff < bestDiff)) {
            best = c.mask;
            bestShared = shared;
            bestDiff = diff;
        }
    }
    return best;
}

int BiomeDatabase::nearestRegion(int combination, const Features& raw) const {
    const int mask = standInCombination(combination);
    if (mask < 0) return -1;
    return nearestRegionOf(static_cast<std::size_t>(combinationIndex(mask)), raw);
}

int BiomeDatabase::nearestRegionOf(std::size_t combinationIdx, const Features& raw) const {
    const DbCombination& c = combinations[combinationIdx];
    Features z{};
    for (std::size_t f = 0; f < kFactorCount; ++f)
        z[f] = featureWeights[f] != 0 ? (raw[f] - c.featureMean[f]) / c.featureStd[f] : 0.0;
    int best = -1;
    double bestD = std::numeric_limits<double>::infinity();
    for (int r = c.firstRegion; r < c.firstRegion + c.k; ++r) {
        const Features& cz = regions[static_cast<std::size_t>(r)].centroidNormalised;
        double d = 0;
        for (std::size_t f = 0; f < kFactorCount; ++f)
            if (featureWeights[f] != 0) d += (z[f] - cz[f]) * (z[f] - cz[f]);  // weights are 0 or 1
        if (d < bestD) {
            bestD = d;
            best = r;
        }
    }
    return best < 0 ? c.firstRegion : best;
}

bool BiomeDatabase::hasContext() const {
    if (schemaVersion < 3 || contextBins.edgesM.empty()) return false;
    const std::size_t nc = static_cast<std::size_t>(contextBins.count()), ns = speciesNames.size();
    const std::size_t nb = static_cast<std::size_t>(pcfBins.count);
    for (const DbRegion& r : regions)
        if (r.contextAreaM2.size() != nc || r.contextSpeciesCount.size() != ns * nc || r.heightCovered.size() != ns ||
            r.contextCellPairs.size() != nc * nc * nb)
            return false;
    return true;
}

// ---------------------------------------------------------------------------------------
// Writing

void writeBiomeDatabase(const std::string& path, const BiomeDatabase& db) {
    const std::size_t ns = db.speciesNames.size();
    const std::size_t nb = static_cast<std::size_t>(db.pcfBins.count);
    const std::size_t nsep = static_cast<std::size_t>(db.separationBins.count);
    if (db.canopySubBiomeMask.size() != ns)
        throw ValidationError(path + ": canopy sub-biome masks (" + std::to_string(db.canopySubBiomeMask.size()) +
                              ") do not match the species (" + std::to_string(ns) + ")");

    // A database without canopy-context statistics (every region's empty, e.g. one built
    // in code from other statistics) is written as schema 2, which has none.
    bool anyContext = false;
    for (const auto& r : db.regions)
        anyContext = anyContext || !r.contextAreaM2.empty() || !r.contextSpeciesCount.empty() ||
                     !r.heightCovered.empty() || !r.contextCellPairs.empty();
    const bool withContext = db.hasContext();
    if (anyContext && !withContext)
        throw ValidationError(path + ": canopy context statistics are missing in some regions or have the wrong size");

    AtomicOutput out(path);
    {
        h5::File f = h5::File::create(out.tempPath());
        f.setAttr("/", "format", std::string(kBiomeDbFormat));
        f.setAttr("/", "schema_version", static_cast<std::int64_t>(withContext ? kBiomeDbSchemaVersion : 2));
        f.setAttr("/", "code_version", db.codeVersion);
        f.setAttr("/", "biome_name", db.biomeName);
        f.setAttr("/", "biome_toml", db.biomeToml);
        std::string units = "lengths m, areas m2, densities plants/m2";
        for (const FactorInfo& fi : kFactors) units += std::string(", ") + fi.key + " " + fi.unit;
        f.setAttr("/", "units", units);
        f.setAttr("/", "seeding_radius_factor", db.seedingRadiusFactor);

        f.writeStrings("/species/names", db.speciesNames);
        f.writeI32("/species/canopy_subbiome_mask",
                   std::vector<std::int32_t>(db.canopySubBiomeMask.begin(), db.canopySubBiomeMask.end()), {hs(ns)}, "1");
        f.writeStrings("/sub_biomes/names", db.subBiomeNames);
        std::vector<std::string> catNames;
        std::vector<std::int32_t> catLayer, catSpecies;
        for (int c = 0; c < db.categoryCount(); ++c) {
            catNames.push_back(db.categoryName(c));
            catLayer.push_back(static_cast<std::int32_t>(BiomeDatabase::layerOf(c, static_cast<int>(ns))));
            catSpecies.push_back(static_cast<std::int32_t>(static_cast<std::size_t>(c) % std::max<std::size_t>(ns, 1)));
        }
        f.writeStrings("/categories/names", catNames);
        f.writeI32("/categories/layer", catLayer, {hs(catLayer.size())}, "1");
        f.writeI32("/categories/species", catSpecies, {hs(catSpecies.size())}, "1");
        std::vector<std::string> featureNames, featureUnits;
        for (const FactorInfo& fi : kFactors) {
            featureNames.emplace_back(fi.key);
            featureUnits.emplace_back(fi.unit);
        }
        f.writeStrings("/features/names", featureNames);
        f.writeStrings("/features/units", featureUnits);
        f.writeF64("/features/weights", std::vector<double>(db.featureWeights.begin(), db.featureWeights.end()),
                   {hs(kFactorCount)}, "1");

        std::vector<std::string> pNames, pValues;
        for (const auto& [k, v] : db.parameters) {
            pNames.push_back(k);
            pValues.push_back(v);
        }
        f.writeStrings("/parameters/names", pNames);
        f.writeStrings("/parameters/values", pValues);
        out.midWritePoint();

        f.ensureGroup("/bins");
        f.setAttr("/bins", "pcf_rmax_m", db.pcfBins.rMaxM);
        f.setAttr("/bins", "pcf_bins", static_cast<std::int64_t>(db.pcfBins.count));
        f.setAttr("/bins", "separation_min_m", db.separationBins.minM);
        f.setAttr("/bins", "separation_max_m", db.separationBins.maxM);
        f.setAttr("/bins", "separation_bins", static_cast<std::int64_t>(db.separationBins.count));
        f.writeF64("/bins/pcf_edges_m", db.pcfBins.edgesM(), {hs(nb + 1)}, "m");
        std::vector<double> annulus(nb);
        for (std::size_t k = 0; k < nb; ++k) annulus[k] = db.pcfBins.annulusAreaM2(static_cast<int>(k));
        f.writeF64("/bins/pcf_annulus_area_m2", annulus, {hs(nb)}, "m2");
        f.writeF64("/bins/separation_edges_m", db.separationBins.edgesM(), {hs(nsep + 1)}, "m");
        const std::size_t nctx = static_cast<std::size_t>(db.contextBins.count());
        if (withContext) {
            db.contextBins.validate(path + ": canopy context bins");
            f.writeF64("/bins/context_edges_m", db.contextBins.edgesM, {hs(nctx - 1)}, "m");
        }

        f.ensureGroup("/inputs");
        f.setAttr("/inputs", "count", static_cast<std::int64_t>(db.inputs.size()));
        for (std::size_t i = 0; i < db.inputs.size(); ++i) {
            const DbInput& in = db.inputs[i];
            const std::string g = inputGroup(i);
            f.ensureGroup(g);
            f.setAttr(g, "path", in.path);
            f.setAttr(g, "abiotics", in.abioticsPath);
            f.setAttr(g, "terrain", in.terrainPath);
            f.setAttr(g, "canopy", in.canopyPath);
            f.setAttr(g, "seed", static_cast<std::int64_t>(in.seed));  // the uint64's bits
            f.setAttr(g, "year", static_cast<std::int64_t>(in.year));
            f.setAttr(g, "window_m", std::vector<double>{in.window.x0, in.window.y0, in.window.x1, in.window.y1});
            f.setAttr(g, "undergrowth_plants", in.undergrowthPlants);
            f.setAttr(g, "canopy_trees", in.canopyTrees);
            f.setAttr(g, "unlabelled_plants", in.unlabelledPlants);
            f.setAttr(g, "unlabelled_area_m2", in.unlabelledAreaM2);
            f.setAttr(g, "parameters", in.parameters);
        }

        const std::size_t nc = db.combinations.size();
        std::size_t kMaxTried = 1;
        for (const auto& c : db.combinations) kMaxTried = std::max(kMaxTried, c.silhouette.size());
        std::vector<std::int32_t> cMask, cK, cFirst;
        std::vector<double> cArea, cCells;
        for (const auto& c : db.combinations) {
            cMask.push_back(c.mask);
            cK.push_back(c.k);
            cFirst.push_back(c.firstRegion);
            cArea.push_back(c.areaM2);
            cCells.push_back(static_cast<double>(c.cellCount));
        }
        f.ensureGroup("/combinations");
        f.writeI32("/combinations/mask", cMask, {hs(nc)}, "1");
        f.writeI32("/combinations/k", cK, {hs(nc)}, "1");
        f.writeI32("/combinations/first_region", cFirst, {hs(nc)}, "1");
        f.writeF64("/combinations/area_m2", cArea, {hs(nc)}, "m2");
        f.writeF64("/combinations/cell_count", cCells, {hs(nc)}, "1");
        f.writeF64("/combinations/feature_mean",
                   flatten(db.combinations, kFactorCount, [](const DbCombination& c) { return featuresRow(c.featureMean); }),
                   {hs(nc), kFactorCount}, kPerFeatureUnits);
        f.writeF64("/combinations/feature_std",
                   flatten(db.combinations, kFactorCount, [](const DbCombination& c) { return featuresRow(c.featureStd); }),
                   {hs(nc), kFactorCount}, kPerFeatureUnits);
        f.writeF64("/combinations/silhouette",
                   flatten(db.combinations, kMaxTried, [](const DbCombination& c) -> const std::vector<double>& { return c.silhouette; }),
                   {hs(nc), hs(kMaxTried)}, "1");

        const std::size_t nr = db.regions.size();
        std::vector<std::int32_t> rComb, rCluster;
        std::vector<double> rArea, rCells, rUnder, rCanopy, rDensity;
        for (const auto& r : db.regions) {
            rComb.push_back(r.combination);
            rCluster.push_back(r.cluster);
            rArea.push_back(r.areaM2);
            rCells.push_back(static_cast<double>(r.cellCount));
            rUnder.push_back(r.undergrowthCount);
            rCanopy.push_back(r.canopyCount);
            rDensity.push_back(r.densityPerM2);
        }
        f.ensureGroup("/regions");
        f.setAttr("/regions", "count", static_cast<std::int64_t>(nr));
        f.writeI32("/regions/combination", rComb, {hs(nr)}, "1");
        f.writeI32("/regions/cluster", rCluster, {hs(nr)}, "1");
        f.writeF64("/regions/centroid_normalised",
                   flatten(db.regions, kFactorCount, [](const DbRegion& r) { return featuresRow(r.centroidNormalised); }),
                   {hs(nr), kFactorCount}, "1");
        f.writeF64("/regions/centroid_raw",
                   flatten(db.regions, kFactorCount, [](const DbRegion& r) { return featuresRow(r.centroidRaw); }),
                   {hs(nr), kFactorCount}, kPerFeatureUnits);
        f.writeF64("/regions/area_m2", rArea, {hs(nr)}, "m2");
        f.writeF64("/regions/cell_count", rCells, {hs(nr)}, "1");
        f.writeF64("/regions/undergrowth_count", rUnder, {hs(nr)}, "1");
        f.writeF64("/regions/canopy_count", rCanopy, {hs(nr)}, "1");
        f.writeF64("/regions/density_per_m2", rDensity, {hs(nr)}, "m-2");
        const std::size_t ni = db.inputs.size();
        if (ni > 0 && std::all_of(db.regions.begin(), db.regions.end(), [&](const DbRegion& r) { return r.inputAreaM2.size() == ni; }))
            f.writeF64("/regions/input_area_m2",
                       flatten(db.regions, ni, [](const DbRegion& r) -> const std::vector<double>& { return r.inputAreaM2; }),
                       {hs(nr), hs(ni)}, "m2");
        f.writeF64("/regions/species_count",
                   flatten(db.regions, ns, [](const DbRegion& r) -> const std::vector<double>& { return r.speciesCount; }),
                   {hs(nr), hs(ns)}, "1");
        f.writeF64("/regions/species_proportion",
                   flatten(db.regions, ns, [](const DbRegion& r) -> const std::vector<double>& { return r.speciesProportion; }),
                   {hs(nr), hs(ns)}, "1");
        f.writeF64("/regions/canopy_species_count",
                   flatten(db.regions, ns, [](const DbRegion& r) -> const std::vector<double>& { return r.canopySpeciesCount; }),
                   {hs(nr), hs(ns)}, "1");

        for (std::size_t ri = 0; ri < nr; ++ri) {
            const DbRegion& r = db.regions[ri];
            const std::string g = regionGroup(ri);
            f.ensureGroup(g);
            f.setAttr(g, "combination", static_cast<std::int64_t>(r.combination));
            f.setAttr(g, "cluster", static_cast<std::int64_t>(r.cluster));
            for (int which = 0; which < 2; ++which) {
                const auto& hists = which == 0 ? r.height : r.crownRadius;
                const std::string stem = g + (which == 0 ? "/height" : "/crown_radius");
                if (hists.size() != ns)
                    throw ValidationError(path + ": region " + std::to_string(ri) + ": size histograms for " +
                                          std::to_string(hists.size()) + " species, expected " + std::to_string(ns));
                const std::size_t bins = ns ? hists[0].counts.size() : 0;
                for (const auto& h : hists)
                    if (h.counts.size() != bins || h.edges.size() != bins + 1)
                        throw ValidationError(path + ": region " + std::to_string(ri) +
                                              ": size histograms must all have the same number of bins");
                f.writeF64(stem + "_edges_m", flatten(hists, bins + 1, [](const DbHistogram& h) -> const std::vector<double>& { return h.edges; }),
                           {hs(ns), hs(bins + 1)}, "m");
                f.writeF64(stem + "_counts", flatten(hists, bins, [](const DbHistogram& h) -> const std::vector<double>& { return h.counts; }),
                           {hs(ns), hs(bins)}, "1");
                std::vector<double> over;
                for (const auto& h : hists) over.push_back(h.overflow);
                f.writeF64(stem + "_overflow", over, {hs(ns)}, "1");
            }
            if (withContext) {
            f.writeF64(g + "/context_area_m2", r.contextAreaM2, {hs(nctx)}, "m2");
            f.writeF64(g + "/context_species_count", r.contextSpeciesCount, {hs(ns), hs(nctx)}, "1");
            {
                const std::size_t bins = ns ? r.height[0].counts.size() : 0;
                for (std::size_t s = 0; s < ns; ++s)
                    if (r.heightCovered[s].counts.size() != bins)
                        throw ValidationError(path + ": region " + std::to_string(ri) +
                                              ": heights under crowns must have the bins of the heights");
                f.writeF64(g + "/height_covered_counts",
                           flatten(r.heightCovered, bins, [](const DbHistogram& h) -> const std::vector<double>& { return h.counts; }),
                           {hs(ns), hs(bins)}, "1");
                std::vector<double> over;
                for (const auto& h : r.heightCovered) over.push_back(h.overflow);
                f.writeF64(g + "/height_covered_overflow", over, {hs(ns)}, "1");
            }
            f.writeF64(g + "/context_cell_pairs", r.contextCellPairs, {hs(nctx), hs(nctx), hs(nb)}, "1");
            }
            const std::size_t np = r.pairs.size();
            std::vector<std::int32_t> src, tgt;
            std::vector<double> norm, under, sources;
            for (const auto& p : r.pairs) {
                if (p.pairCount.size() != nb || p.translateWeighted.size() != nb || p.g.size() != nb ||
                    p.separationCount.size() != nsep)
                    throw ValidationError(path + ": region " + std::to_string(ri) + ": pair " + std::to_string(p.source) +
                                          " -> " + std::to_string(p.target) + " has arrays of the wrong length");
                src.push_back(p.source);
                tgt.push_back(p.target);
                norm.push_back(p.normalisation);
                under.push_back(p.separationUnderflow);
                sources.push_back(p.separationSources);
            }
            const std::string pg = g + "/pairs";
            f.ensureGroup(pg);
            f.writeI32(pg + "/source", src, {hs(np)}, "1");
            f.writeI32(pg + "/target", tgt, {hs(np)}, "1");
            f.writeF64(pg + "/pair_count", flatten(r.pairs, nb, [](const DbPairStats& p) -> const std::vector<double>& { return p.pairCount; }),
                       {hs(np), hs(nb)}, "1");
            f.writeF64(pg + "/translate_weighted",
                       flatten(r.pairs, nb, [](const DbPairStats& p) -> const std::vector<double>& { return p.translateWeighted; }),
                       {hs(np), hs(nb)}, "1");
            f.writeF64(pg + "/normalisation_per_m2", norm, {hs(np)}, "m-2");
            f.writeF64(pg + "/g", flatten(r.pairs, nb, [](const DbPairStats& p) -> const std::vector<double>& { return p.g; }),
                       {hs(np), hs(nb)}, "1");
            f.writeF64(pg + "/separation_count",
                       flatten(r.pairs, nsep, [](const DbPairStats& p) -> const std::vector<double>& { return p.separationCount; }),
                       {hs(np), hs(nsep)}, "1");
            f.writeF64(pg + "/separation_underflow", under, {hs(np)}, "1");
            f.writeF64(pg + "/separation_sources", sources, {hs(np)}, "1");
        }
        std::vector<ProvenanceEntry> measured;
        if (!db.createdUtc.empty()) measured.push_back({"created_utc", db.createdUtc});
        writeProvenance(f, measured);
    }
    out.commit();
}

// ---------------------------------------------------------------------------------------
// Reading

namespace {

/// IoError naming the dataset, the index and the value unless every value is finite and >= 0
/// (counts, areas, densities, g: a NaN or a negative density would give an empty or broken
/// scene without a word).
void requireNonNegative(const std::string& path, const std::string& dataset, const std::vector<double>& v) {
    for (std::size_t i = 0; i < v.size(); ++i)
        if (!(v[i] >= 0) || !std::isfinite(v[i]))
            throw IoError(path + ": " + dataset + ": entry " + std::to_string(i) + " is " + formatNumber(v[i], 6) +
                          "; it must be finite and non-negative");
}

/// IoError unless every value is finite.
void requireFinite(const std::string& path, const std::string& dataset, const std::vector<double>& v) {
    for (std::size_t i = 0; i < v.size(); ++i)
        if (!std::isfinite(v[i]))
            throw IoError(path + ": " + dataset + ": entry " + std::to_string(i) + " is " + formatNumber(v[i], 6) + "; it must be finite");
}

}  // namespace

BiomeDatabase readBiomeDatabase(const std::string& path) {
    const h5::File f = h5::File::openRead(path);
    if (!f.hasAttr("/", "format"))
        throw IoError(path + ": not a biome database (root attribute 'format' is missing; expected '" +
                      std::string(kBiomeDbFormat) + "')");
    const std::string format = f.attrString("/", "format");
    if (format != kBiomeDbFormat)
        throw IoError(path + ": not a biome database (format '" + format + "', expected '" + kBiomeDbFormat + "')");
    if (!f.hasAttr("/", "schema_version")) throw IoError(path + ": root attribute 'schema_version' is missing");
    const std::int64_t version = f.attrInt("/", "schema_version");
    if (version < kBiomeDbOldestReadableVersion || version > kBiomeDbSchemaVersion)
        throw IoError(path + ": biome database schema_version " + std::to_string(version) + " found, versions " +
                      std::to_string(kBiomeDbOldestReadableVersion) + ".." + std::to_string(kBiomeDbSchemaVersion) +
                      " can be read (re-run eco analyse with this version)");

    const Reader rd(f);
    BiomeDatabase db;
    db.schemaVersion = static_cast<int>(version);
    db.codeVersion = f.attrString("/", "code_version");
    // The creation date is provenance (/provenance, docs/hdf5.md); schema 2 and 3 files have
    // it at the root; `eco --no-provenance` leaves it out.
    db.createdUtc = readProvenanceString(f, "created_utc", "created_utc").value_or("");
    db.biomeName = f.attrString("/", "biome_name");
    db.biomeToml = f.attrString("/", "biome_toml");
    db.seedingRadiusFactor = f.attrDouble("/", "seeding_radius_factor");

    db.speciesNames = rd.strings("/species/names", Reader::kAny);
    const std::size_t ns = db.speciesNames.size();
    const auto masks = rd.i32("/species/canopy_subbiome_mask", {ns});
    db.canopySubBiomeMask.assign(masks.begin(), masks.end());
    db.subBiomeNames = rd.strings("/sub_biomes/names", Reader::kAny);
    // The features are read by name, not by schema version (docs/factors.md): a file holds
    // the first nf factors of kFactors, in order. A factor it lacks was added after the file
    // was written: an optional one (files before schema 5 have no wind) gets weight 0 (and
    // mean 0, std 1, centroid 0 below), since the file's regions were found without it; a
    // required one is refused, naming it.
    const auto featureNames = rd.strings("/features/names", Reader::kAny);
    const std::size_t nf = featureNames.size();
    if (nf > kFactorCount)
        throw IoError(path + ": /features/names: " + std::to_string(nf) + " features, this version knows " +
                      std::to_string(kFactorCount) + " (written by a newer eco analyse?)");
    for (std::size_t i = 0; i < nf; ++i)
        if (featureNames[i] != kFactors[i].key)
            throw IoError(path + ": /features/names: feature " + std::to_string(i) + " is '" + featureNames[i] +
                          "', expected '" + kFactors[i].key + "'");
    for (std::size_t i = nf; i < kFactorCount; ++i)
        if (kFactors[i].responseRequired)
            throw IoError(path + ": /features/names: no feature '" + kFactors[i].key + "' (" + std::to_string(nf) +
                          " features): the database was written before the factor " + kFactors[i].label +
                          " existed; re-run eco analyse with this version");
    db.featureWeights.fill(0.0);
    if (f.exists("/features/weights")) {
        const auto w = rd.f64("/features/weights", {nf});
        for (std::size_t i = 0; i < nf; ++i) {
            if (w[i] != 0.0 && w[i] != 1.0)
                throw IoError(path + ": /features/weights: entry " + std::to_string(i) + " is " + formatNumber(w[i], 6) +
                              "; weights are 0 or 1");
            db.featureWeights[i] = w[i];
        }
    } else {
        for (std::size_t i = 0; i < nf; ++i) db.featureWeights[i] = 1.0;
    }
    const auto pNames = rd.strings("/parameters/names", Reader::kAny);
    const auto pValues = rd.strings("/parameters/values", pNames.size());
    for (std::size_t i = 0; i < pNames.size(); ++i) db.parameters.emplace_back(pNames[i], pValues[i]);

    db.pcfBins.rMaxM = f.attrDouble("/bins", "pcf_rmax_m");
    db.pcfBins.count = static_cast<int>(f.attrInt("/bins", "pcf_bins"));
    db.separationBins.minM = f.attrDouble("/bins", "separation_min_m");
    db.separationBins.maxM = f.attrDouble("/bins", "separation_max_m");
    db.separationBins.count = static_cast<int>(f.attrInt("/bins", "separation_bins"));
    try {
        db.pcfBins.validate(path + ": /bins");
        db.separationBins.validate(path + ": /bins");
    } catch (const ValidationError& e) {
        throw IoError(e.what());
    }
    const std::size_t nb = static_cast<std::size_t>(db.pcfBins.count);
    const std::size_t nsep = static_cast<std::size_t>(db.separationBins.count);
    // The edges are written for readers of the file; ours derive them from the attributes,
    // and a file whose edges disagree with its attributes is corrupt.
    const auto requireEdges = [&](const char* dataset, const std::vector<double>& stored, const std::vector<double>& expected) {
        for (std::size_t i = 0; i < expected.size(); ++i)
            if (!(std::abs(stored[i] - expected[i]) <= 1e-9 * std::max(1.0, std::abs(expected[i]))))
                throw IoError(path + ": " + dataset + ": edge " + std::to_string(i) + " is " + formatNumber(stored[i], 9) +
                              ", but the /bins attributes give " + formatNumber(expected[i], 9));
    };
    requireEdges("/bins/pcf_edges_m", rd.f64("/bins/pcf_edges_m", {nb + 1}), db.pcfBins.edgesM());
    requireEdges("/bins/separation_edges_m", rd.f64("/bins/separation_edges_m", {nsep + 1}), db.separationBins.edgesM());
    std::size_t nctx = 0;
    if (version >= 3) {
        const std::size_t ne = rd.length("/bins/context_edges_m");
        db.contextBins.edgesM = rd.f64("/bins/context_edges_m", {ne});
        try {
            db.contextBins.validate(path + ": /bins/context_edges_m");
        } catch (const ValidationError& e) {
            throw IoError(e.what());
        }
        nctx = static_cast<std::size_t>(db.contextBins.count());
    } else {
        db.contextBins.edgesM.clear();
    }

    const std::size_t nIn = static_cast<std::size_t>(f.attrInt("/inputs", "count"));
    for (std::size_t i = 0; i < nIn; ++i) {
        const std::string g = inputGroup(i);
        DbInput in;
        in.path = f.attrString(g, "path");
        in.abioticsPath = f.attrString(g, "abiotics");
        in.terrainPath = f.attrString(g, "terrain");
        in.canopyPath = f.attrString(g, "canopy");
        in.seed = static_cast<std::uint64_t>(f.attrInt(g, "seed"));
        in.year = static_cast<int>(f.attrInt(g, "year"));
        const auto w = f.attrDoubles(g, "window_m");
        if (w.size() != 4) throw IoError(path + ": " + g + ": attribute window_m must have 4 values");
        in.window = RectWindow{w[0], w[1], w[2], w[3]};
        in.undergrowthPlants = f.attrInt(g, "undergrowth_plants");
        in.canopyTrees = f.attrInt(g, "canopy_trees");
        in.unlabelledPlants = f.attrInt(g, "unlabelled_plants");
        in.unlabelledAreaM2 = f.attrDouble(g, "unlabelled_area_m2");
        in.parameters = f.attrString(g, "parameters");
        db.inputs.push_back(in);
    }

    const std::size_t nc = rd.length("/combinations/mask");
    const auto cMask = rd.i32("/combinations/mask", {nc});
    const auto cK = rd.i32("/combinations/k", {nc});
    const auto cFirst = rd.i32("/combinations/first_region", {nc});
    const auto cArea = rd.f64("/combinations/area_m2", {nc});
    const auto cCells = rd.f64("/combinations/cell_count", {nc});
    const auto cMean = rd.f64("/combinations/feature_mean", {nc, nf});
    const auto cStd = rd.f64("/combinations/feature_std", {nc, nf});
    const auto silShape = f.shape("/combinations/silhouette");
    if (silShape.size() != 2 || silShape[0] != nc)
        throw IoError(path + ": /combinations/silhouette: expected shape [" + std::to_string(nc) + "][kmax]");
    const std::size_t kTried = static_cast<std::size_t>(silShape[1]);
    const auto cSil = rd.f64("/combinations/silhouette", {nc, kTried});

    requireNonNegative(path, "/combinations/area_m2", cArea);
    requireNonNegative(path, "/combinations/cell_count", cCells);
    requireFinite(path, "/combinations/feature_mean", cMean);
    requireFinite(path, "/combinations/feature_std", cStd);
    const std::size_t nr = rd.length("/regions/combination");
    for (std::size_t i = 0; i < nc; ++i) {
        DbCombination c;
        c.mask = cMask[i];
        c.k = cK[i];
        c.firstRegion = cFirst[i];
        c.areaM2 = cArea[i];
        c.cellCount = static_cast<std::int64_t>(cCells[i]);
        c.featureMean = featuresAt(cMean, i, nf, 0.0);
        c.featureStd = featuresAt(cStd, i, nf, 1.0);
        c.silhouette = rowOf(cSil, i, kTried);
        const int maxMask = (1 << db.subBiomeNames.size()) - 1;
        if (c.mask < 1 || c.mask > maxMask || (i > 0 && c.mask <= cMask[i - 1]))
            throw IoError(path + ": /combinations/mask: combination " + std::to_string(i) + " has mask " +
                          std::to_string(c.mask) + "; masks must lie in 1.." + std::to_string(maxMask) +
                          " (one bit per sub-biome) and increase");
        if (c.k < 1 || c.firstRegion < 0 || static_cast<std::size_t>(c.firstRegion + c.k) > nr)
            throw IoError(path + ": /combinations: combination " + std::to_string(c.mask) + " refers to regions " +
                          std::to_string(c.firstRegion) + " .. " + std::to_string(c.firstRegion + c.k - 1) + " of " +
                          std::to_string(nr));
        for (std::size_t f = 0; f < kFactorCount; ++f)  // a factor left out (weight 0) is never divided by
            if (db.featureWeights[f] != 0 && !(c.featureStd[f] > 0.0))
                throw IoError(path + ": /combinations/feature_std: non-positive normalisation");
        db.combinations.push_back(std::move(c));
    }

    const auto rComb = rd.i32("/regions/combination", {nr});
    const auto rCluster = rd.i32("/regions/cluster", {nr});
    const auto rCz = rd.f64("/regions/centroid_normalised", {nr, nf});
    const auto rCr = rd.f64("/regions/centroid_raw", {nr, nf});
    const auto rArea = rd.f64("/regions/area_m2", {nr});
    const auto rCells = rd.f64("/regions/cell_count", {nr});
    const auto rUnder = rd.f64("/regions/undergrowth_count", {nr});
    const auto rCanopy = rd.f64("/regions/canopy_count", {nr});
    const auto rDensity = rd.f64("/regions/density_per_m2", {nr});
    const auto rSpecies = rd.f64("/regions/species_count", {nr, ns});
    const auto rProp = rd.f64("/regions/species_proportion", {nr, ns});
    const auto rCanSp = rd.f64("/regions/canopy_species_count", {nr, ns});
    requireFinite(path, "/regions/centroid_normalised", rCz);
    requireFinite(path, "/regions/centroid_raw", rCr);
    for (const auto& [name, v] : {std::pair<const char*, const std::vector<double>*>{"/regions/area_m2", &rArea},
                                  {"/regions/cell_count", &rCells},
                                  {"/regions/undergrowth_count", &rUnder},
                                  {"/regions/canopy_count", &rCanopy},
                                  {"/regions/density_per_m2", &rDensity},
                                  {"/regions/species_count", &rSpecies},
                                  {"/regions/species_proportion", &rProp},
                                  {"/regions/canopy_species_count", &rCanSp}})
        requireNonNegative(path, name, *v);
    // Per input (optional: files before it was recorded have none): non-negative, and each
    // row adds up to the region's area.
    std::vector<double> rInputArea;
    if (f.exists("/regions/input_area_m2")) {
        const std::size_t ni = db.inputs.size();
        rInputArea = rd.f64("/regions/input_area_m2", {nr, ni});
        requireNonNegative(path, "/regions/input_area_m2", rInputArea);
        for (std::size_t ri = 0; ri < nr; ++ri) {
            double sum = 0;
            for (std::size_t i = 0; i < ni; ++i) sum += rInputArea[ri * ni + i];
            if (std::abs(sum - rArea[ri]) > 1e-6 * std::max(1.0, rArea[ri]))
                throw IoError(path + ": /regions/input_area_m2: region " + std::to_string(ri) + " adds up to " +
                              formatNumber(sum, 10) + " m^2 but /regions/area_m2 is " + formatNumber(rArea[ri], 10));
        }
    }
    for (std::size_t i = 0; i < rProp.size(); ++i)
        if (rProp[i] > 1 + 1e-9)
            throw IoError(path + ": /regions/species_proportion: entry " + std::to_string(i) + " is " + formatNumber(rProp[i], 6) +
                          "; a share must lie in [0, 1]");
    for (const DbCombination& c : db.combinations)
        for (int k = 0; k < c.k; ++k) {
            const std::size_t ri = static_cast<std::size_t>(c.firstRegion + k);
            if (rComb[ri] != c.mask || rCluster[ri] != k)
                throw IoError(path + ": /regions: region " + std::to_string(ri) + " has combination " +
                              std::to_string(rComb[ri]) + ", cluster " + std::to_string(rCluster[ri]) +
                              " but /combinations assigns it combination " + std::to_string(c.mask) + ", cluster " +
                              std::to_string(k));
        }
    for (std::size_t ri = 0; ri < nr; ++ri) {
        DbRegion r;
        r.combination = rComb[ri];
        r.cluster = rCluster[ri];
        r.centroidNormalised = featuresAt(rCz, ri, nf, 0.0);
        r.centroidRaw = featuresAt(rCr, ri, nf, 0.0);
        r.areaM2 = rArea[ri];
        r.cellCount = static_cast<std::int64_t>(rCells[ri]);
        r.undergrowthCount = rUnder[ri];
        r.canopyCount = rCanopy[ri];
        r.densityPerM2 = rDensity[ri];
        if (!rInputArea.empty()) r.inputAreaM2 = rowOf(rInputArea, ri, db.inputs.size());
        r.speciesCount = rowOf(rSpecies, ri, ns);
        r.speciesProportion = rowOf(rProp, ri, ns);
        r.canopySpeciesCount = rowOf(rCanSp, ri, ns);
        const std::string g = regionGroup(ri);
        for (int which = 0; which < 2; ++which) {
            const std::string stem = g + (which == 0 ? "/height" : "/crown_radius");
            const auto shape = f.shape(stem + "_counts");
            if (shape.size() != 2 || shape[0] != ns)
                throw IoError(path + ": " + stem + "_counts: expected shape [" + std::to_string(ns) + "][bins]");
            const std::size_t bins = static_cast<std::size_t>(shape[1]);
            const auto edges = rd.f64(stem + "_edges_m", {ns, bins + 1});
            const auto counts = rd.f64(stem + "_counts", {ns, bins});
            const auto over = rd.f64(stem + "_overflow", {ns});
            requireNonNegative(path, stem + "_edges_m", edges);
            requireNonNegative(path, stem + "_counts", counts);
            requireNonNegative(path, stem + "_overflow", over);
            for (std::size_t sp = 0; sp < ns; ++sp)
                for (std::size_t b = 0; b < bins; ++b)
                    if (!(edges[sp * (bins + 1) + b + 1] > edges[sp * (bins + 1) + b]))
                        throw IoError(path + ": " + stem + "_edges_m: the edges of species " + std::to_string(sp) +
                                      " must increase (edge " + std::to_string(b + 1) + " is " +
                                      formatNumber(edges[sp * (bins + 1) + b + 1], 6) + " after " +
                                      formatNumber(edges[sp * (bins + 1) + b], 6) + ")");
            auto& hists = which == 0 ? r.height : r.crownRadius;
            for (std::size_t s = 0; s < ns; ++s)
                hists.push_back(DbHistogram{rowOf(edges, s, bins + 1), rowOf(counts, s, bins), over[s]});
        }
        if (version >= 3) {
            r.contextAreaM2 = rd.f64(g + "/context_area_m2", {nctx});
            r.contextSpeciesCount = rd.f64(g + "/context_species_count", {ns, nctx});
            const std::size_t bins = ns ? r.height[0].counts.size() : 0;
            const auto cc = rd.f64(g + "/height_covered_counts", {ns, bins});
            const auto co = rd.f64(g + "/height_covered_overflow", {ns});
            for (std::size_t s = 0; s < ns; ++s) r.heightCovered.push_back(DbHistogram{r.height[s].edges, rowOf(cc, s, bins), co[s]});
            r.contextCellPairs = rd.f64(g + "/context_cell_pairs", {nctx, nctx, nb});
            const std::pair<const char*, const std::vector<double>*> contextSets[] = {
                {"context_area_m2", &r.contextAreaM2},
                {"context_species_count", &r.contextSpeciesCount},
                {"context_cell_pairs", &r.contextCellPairs}};
            for (const auto& [name, v] : contextSets)
                for (std::size_t i = 0; i < v->size(); ++i)
                    if (!((*v)[i] >= 0) || !std::isfinite((*v)[i]))
                        throw IoError(path + ": " + g + "/" + name + ": entry " + std::to_string(i) + " is " +
                                      formatNumber((*v)[i], 6) + "; it must be finite and non-negative");
        }
        const std::string pg = g + "/pairs";
        const std::size_t np = rd.length(pg + "/source");
        const auto src = rd.i32(pg + "/source", {np});
        const auto tgt = rd.i32(pg + "/target", {np});
        const auto cnt = rd.f64(pg + "/pair_count", {np, nb});
        const auto tw = rd.f64(pg + "/translate_weighted", {np, nb});
        const auto norm = rd.f64(pg + "/normalisation_per_m2", {np});
        const auto gg = rd.f64(pg + "/g", {np, nb});
        const auto sep = rd.f64(pg + "/separation_count", {np, nsep});
        const auto under = rd.f64(pg + "/separation_underflow", {np});
        const auto sources = rd.f64(pg + "/separation_sources", {np});
        for (const auto& [name, v] : {std::pair<const char*, const std::vector<double>*>{"/pair_count", &cnt},
                                      {"/translate_weighted", &tw},
                                      {"/normalisation_per_m2", &norm},
                                      {"/g", &gg},
                                      {"/separation_count", &sep},
                                      {"/separation_underflow", &under},
                                      {"/separation_sources", &sources}})
            requireNonNegative(path, pg + name, *v);
        for (std::size_t p = 0; p < np; ++p) {
            DbPairStats ps;
            ps.source = src[p];
            ps.target = tgt[p];
            if (ps.source < 0 || ps.target < 0 || ps.source >= db.categoryCount() || ps.target >= db.categoryCount())
                throw IoError(path + ": " + pg + ": pair " + std::to_string(p) + " has a category outside 0.." +
                              std::to_string(db.categoryCount() - 1));
            ps.pairCount = rowOf(cnt, p, nb);
            ps.translateWeighted = rowOf(tw, p, nb);
            ps.normalisation = norm[p];
            ps.g = rowOf(gg, p, nb);
            ps.separationCount = rowOf(sep, p, nsep);
            ps.separationUnderflow = under[p];
            ps.separationSources = sources[p];
            r.pairs.push_back(std::move(ps));
        }
        std::sort(r.pairs.begin(), r.pairs.end(), [](const DbPairStats& a, const DbPairStats& b) {
            return std::make_pair(a.source, a.target) < std::make_pair(b.source, b.target);
        });
        db.regions.push_back(std::move(r));
    }
    return db;
}

}  // namespace eco
