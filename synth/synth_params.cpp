// The parameters of undergrowth synthesis and refinement described once (core/param_desc.h):
// validation with its messages, the scene file's record and docs/synth.md's table (tested)
// come from synthParamFields() and refineParamFields(). Kept apart from the samplers so
// that a parameter's description and its record change in one place.
#include <cmath>

#include "error.h"
#include "text_format.h"
#include "undergrowth.h"

namespace eco::synth {

namespace {

// Scene files record reals with ten significant digits.
constexpr int kRecordDigits = 10;

std::string num(double v) { return formatNumber(v, kRecordDigits); }

}  // namespace

const std::vector<SynthParamField>& synthParamFields() {
    using K = SynthParamField::Kind;
    using R = ParamRange;
    using P = SynthParams;
    static const std::vector<SynthParamField> fields = {
        {"seed", "random seed of sampling and refinement", "", K::Seed, nullptr, nullptr, R::any(), &P::seed},
        {"seed_inner_radius_factor",
         "seeding kernel: full weight within this x crown radius (the outer radius is the database's "
         "`seeding_radius_factor`)", "crown radii",
         K::Real, &P::seedInnerRadiusFactor, nullptr, R::atLeast(0)},
        {"trunk_exclusion_factor", "no undergrowth within this x crown radius of a canopy trunk", "crown radii", K::Real,
         &P::trunkExclusionFactor, nullptr, R{R::Bound::Closed, 0, R::Bound::Open, 1}},
        {"max_passes", "dart-throwing passes at most", "", K::Integer, nullptr, &P::maxPasses, R::closed(1, 10000)},
        {"candidate_oversample", "darts per missing plant in a pass (structured: doubled in each later pass)", "", K::Real,
         &P::candidateOversample, nullptr, R::closed(1, 100)},
        {"cluster_sigma_min_m", "structured: smallest cluster scale searched", "m", K::Real, &P::clusterSigmaMinM,
         nullptr, R::above(0)},
        // Also at least cluster_sigma_min_m (SynthParams::validate).
        {"cluster_sigma_max_m", "structured: largest cluster scale searched, at least the smallest", "m", K::Real,
         &P::clusterSigmaMaxM, nullptr, R::openClosed(0, 1000)},
        {"cluster_min_plants", "structured: fewer plants of a species in a region: the pooled clustering", "",
         K::Integer, nullptr, &P::clusterMinPlants, R::atLeast(0)},
        {"quota_tile_m", "structured: quotas per (region, species, tile of this side); 0 = per region", "m", K::Real,
         &P::quotaTileM, nullptr, R::atLeast(0)},
        {"hard_core_g", "structured: inhibition where the database's g stays below this in the leading bins", "",
         K::Real, &P::hardCoreG, nullptr, R::closed(0, 1)},
        {"hard_core_min_expected_pairs",
         "structured: ... of those bins where a Poisson pattern has at least this many pairs", "", K::Real,
         &P::hardCoreMinExpectedPairs, nullptr, R::atLeast(0)},
    };
    return fields;
}

void SynthParams::validate() const {
    validateParams(*this, synthParamFields(), "synthesis parameter");
    deussen.validate();
    xu.validate();
    if (!(clusterSigmaMaxM >= clusterSigmaMinM))
        throw ValidationError("synthesis parameter 'cluster_sigma_max_m' must be >= cluster_sigma_min_m (" +
                              num(clusterSigmaMinM) + "), got " + num(clusterSigmaMaxM));
}

const char* toString(SynthMethod m) {
    switch (m) {
        case SynthMethod::Darts: return "darts";
        case SynthMethod::Deussen: return "deussen";
        case SynthMethod::Xu2015: return "xu2015";
        case SynthMethod::Structured: break;
    }
    return "structured";
}

SynthMethod parseSynthMethod(const std::string& name) {
    if (name == "structured") return SynthMethod::Structured;
    if (name == "darts") return SynthMethod::Darts;
    if (name == "deussen") return SynthMethod::Deussen;
    if (name == "xu2015") return SynthMethod::Xu2015;
    throw ValidationError("synthesis: method '" + name + "' is not known (structured, darts, deussen or xu2015)");
}

std::vector<std::pair<std::string, std::string>> SynthParams::asParameters() const {
    std::vector<std::pair<std::string, std::string>> out = {{"method", toString(method)}};
    for (const auto& f : synthParamFields()) out.emplace_back(f.key, paramText(f, *this, kRecordDigits));
    // Only with the method that reads them: the other methods' records stay as they were.
    if (method == SynthMethod::Deussen)
        for (auto& kv : deussen.asParameters()) out.push_back(std::move(kv));
    if (method == SynthMethod::Xu2015)
        for (auto& kv : xu.asParameters()) out.push_back(std::move(kv));
    return out;
}

std::vector<h5::NamedAttr> SynthParams::asAttributes() const {
    std::vector<h5::NamedAttr> out = {{"method", std::string(toString(method))}};
    for (const auto& f : synthParamFields()) out.push_back(paramAttr(f, *this));
    if (method == SynthMethod::Deussen)
        for (auto& a : deussen.asAttributes()) out.push_back(std::move(a));
    if (method == SynthMethod::Xu2015)
        for (auto& a : xu.asAttributes()) out.push_back(std::move(a));
    return out;
}

const std::vector<DeussenParamField>& deussenParamFields() {
    using K = DeussenParamField::Kind;
    using R = ParamRange;
    using P = DeussenParams;
    static const std::vector<DeussenParamField> fields = {
        {"deussen_lloyd_iterations", "Lloyd relaxation steps (0: half-toned positions kept)", "",
         K::Integer, nullptr, &P::lloydIterations, R::closed(0, 1000)},
        {"deussen_halftone_fill",
         "half-toning cell: terrain cell / k, k the smallest giving at most this many expected plants of the species "
         "in a cell where it is densest", "",
         K::Real, &P::halftoneFill, nullptr, R::openClosed(0, 1)},
        {"deussen_halftone_tile_m", "error diffusion in square tiles of this side, each on its own (parallel)", "m",
         K::Real, &P::halftoneTileM, nullptr, R::closed(1, 1e6)},
        {"deussen_min_distance_factor",
         "plants of one species at least this x its mean crown radius apart (any pair at "
         "least the database's hard-core distance)", "crown radii",
         K::Real, &P::minDistanceFactor, nullptr, R::closed(0, 10)},
        {"deussen_voronoi_samples", "Voronoi centroid from the centres of a samples x samples lattice per plant", "",
         K::Integer, nullptr, &P::voronoiSamples, R::closed(1, 64)},
        {"deussen_voronoi_radius_factor",
         "... in a square of half-side this / sqrt(the species' density at the plant)", "", K::Real,
         &P::voronoiRadiusFactor, nullptr, R::closed(0.25, 4)},
    };
    return fields;
}

const std::vector<XuParamField>& xuParamFields() {
    using K = XuParamField::Kind;
    using R = ParamRange;
    using P = XuParams;
    static const std::vector<XuParamField> fields = {
        {"xu_radius_factor", "neighbourhood radius R = this / sqrt(the exemplar's density)", "", K::Real, &P::radiusFactor, nullptr,
         R::closed(0.5, 10)},
        {"xu_shells", "rings of equal width in the neighbourhood disc", "", K::Integer, nullptr, &P::shells, R::closed(1, 16)},
        {"xu_sectors", "sectors of the neighbourhood disc", "", K::Integer, nullptr, &P::sectors, R::closed(1, 64)},
        {"xu_sigma", "adjacency smoothing of the histogram distance, a_ij = exp(-d(i, j) / sigma) (0 = none)", "", K::Real, &P::sigma, nullptr,
         R::closed(0, 100)},
        {"xu_candidates", "exemplar elements compared per extension, a random subset (0 = all)", "", K::Integer, nullptr,
         &P::candidates, R::closed(0, 1000000)},
        {"xu_verify_best",
         "of the candidates, this many nearest by histogram are tried and the copy with the fewest conflicts wins (1 = "
         "the paper's nearest alone)", "",
         K::Integer, nullptr, &P::verifyBest, R::closed(1, 1000)},
        {"xu_density_tolerance",
         "drift of the running count from the exemplar's density allowed in that choice, in expected neighbourhoods "
         "(0 = no density feedback)", "",
         K::Real, &P::densityTolerance, nullptr, R::closed(0, 1e6)},
        {"xu_min_distance_factor", "copies refused closer than this x the exemplar's shortest nearest-neighbour distance", "",
         K::Real, &P::minDistanceFactor, nullptr, R::closed(0, 10)},
        {"xu_tile_m", "grown in square tiles of this side, in parallel (0 = one tile)", "m", K::Real, &P::tileM, nullptr,
         R::closed(0, 1e6)},
    };
    return fields;
}

void XuParams::validate() const { validateParams(*this, xuParamFields(), "Xu 2015 sampler parameter"); }

std::vector<std::pair<std::string, std::string>> XuParams::asParameters() const {
    std::vector<std::pair<std::string, std::string>> out;
    for (const auto& f : xuParamFields()) out.emplace_back(f.key, paramText(f, *this, kRecordDigits));
    return out;
}

std::vector<h5::NamedAttr> XuParams::asAttributes() const {
    std::vector<h5::NamedAttr> out;
    for (const auto& f : xuParamFields()) out.push_back(paramAttr(f, *this));
    return out;
}

void DeussenParams::validate() const { validateParams(*this, deussenParamFields(), "Deussen sampler parameter"); }

std::vector<std::pair<std::string, std::string>> DeussenParams::asParameters() const {
    std::vector<std::pair<std::string, std::string>> out;
    for (const auto& f : deussenParamFields()) out.emplace_back(f.key, paramText(f, *this, kRecordDigits));
    return out;
}

std::vector<h5::NamedAttr> DeussenParams::asAttributes() const {
    std::vector<h5::NamedAttr> out;
    for (const auto& f : deussenParamFields()) out.push_back(paramAttr(f, *this));
    return out;
}

const std::vector<RefineParamField>& refineParamFields() {
    using K = RefineParamField::Kind;
    using R = ParamRange;
    using P = RefineParams;
    static const std::vector<RefineParamField> fields = {
        {"refine_sweeps", "proposals per plant", "", K::Integer, nullptr, &P::sweeps, R::closed(0, 100000)},
        {"refine_move_radius_m", "displacement proposals: uniform in a disc of this radius", "m", K::Real,
         &P::moveRadiusM, nullptr, R::above(0), nullptr, "must be positive"},
        {"refine_swap_radius_m", "swap proposals: a partner within this distance", "m", K::Real, &P::swapRadiusM,
         nullptr, R::above(0), nullptr, "must be positive"},
        {"refine_swap_probability", "share of swap proposals", "", K::Real, &P::swapProbability, nullptr, R::closed(0, 1)},
        {"refine_rmax_m", "pair correlation matched up to this distance; 0 = automatic", "m", K::Real, &P::rMaxM,
         nullptr, R::atLeast(0)},
        {"refine_auto_neighbours", "neighbours per plant the automatic range aims at", "", K::Real, &P::autoNeighbours,
         nullptr, R::above(0), nullptr, "must be positive"},
    };
    return fields;
}

void RefineParams::validate() const {
    validateParams(*this, refineParamFields(), "refinement parameter");
    if (useWindow) window.validate("refinement window");
}

std::vector<std::pair<std::string, std::string>> RefineParams::asParameters() const {
    std::vector<std::pair<std::string, std::string>> out;
    for (const auto& f : refineParamFields()) out.emplace_back(f.key, paramText(f, *this, kRecordDigits));
    out.emplace_back("refine_window", useWindow ? num(window.x0) + "," + num(window.y0) + "," + num(window.x1) + "," +
                                                      num(window.y1)
                                                : std::string("none"));
    out.emplace_back("refine_distance_sources", std::to_string(distanceSources));
    out.emplace_back("refine_seed", std::to_string(seed));  // the synthesis seed (pipeline/synth_stages.cpp)
    return out;
}

std::vector<h5::NamedAttr> RefineParams::asAttributes() const {
    std::vector<h5::NamedAttr> out;
    for (const auto& f : refineParamFields()) out.push_back(paramAttr(f, *this));
    // The window as [x0, y0, x1, y1] metres, or the text "none" when refinement covers the scene.
    if (useWindow) out.push_back({"refine_window", std::vector<double>{window.x0, window.y0, window.x1, window.y1}});
    else out.push_back({"refine_window", std::string("none")});
    out.push_back({"refine_distance_sources", static_cast<std::int64_t>(distanceSources)});
    out.push_back({"refine_seed", static_cast<std::int64_t>(seed)});  // the synthesis seed (pipeline/synth_stages.cpp)
    return out;
}

}  // namespace eco::synth
