#include "forest_floor.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "error.h"
#include "text_format.h"

namespace eco::synth {

namespace {

// Scene files record reals with ten significant digits.
constexpr int kRecordDigits = 10;

std::string num(double v) { return formatNumber(v, kRecordDigits); }

void checkResponse(const Response& r, const std::string& key) {
    if (!std::isfinite(r.c) || !(r.r > 0) || !std::isfinite(r.r))
        throw ValidationError("forest floor: " + key + " needs a finite optimum and a positive range, got " + num(r.c) +
                              " / " + num(r.r));
}

}  // namespace

const std::vector<ParamDesc<ForestFloorParams>>& forestFloorParamFields() {
    using K = ParamDesc<ForestFloorParams>::Kind;
    static const std::vector<ParamDesc<ForestFloorParams>> fields = {
        {"litter_full_alpha", "cumulative crown alpha at which litter density reaches 1", "", K::Real,
         &ForestFloorParams::litterFullAlpha, nullptr, ParamRange::above(0), nullptr, "must be positive"},
    };
    return fields;
}

void ForestFloorParams::validate() const {
    for (std::size_t f = 0; f < kFactorCount; ++f)
        if (!grass[f].isIndifferent()) checkResponse(grass[f], std::string("grass_") + kFactors[f].key);
    validateParams(*this, forestFloorParamFields(), "forest floor parameter");
}

std::vector<std::pair<std::string, std::string>> ForestFloorParams::asParameters() const {
    std::vector<std::pair<std::string, std::string>> out;
    for (std::size_t f = 0; f < kFactorCount; ++f) {
        if (grass[f].isIndifferent()) continue;
        const std::string key = std::string("grass_") + kFactors[f].key;
        out.emplace_back(key + "_c", num(grass[f].c));
        out.emplace_back(key + "_r", num(grass[f].r));
    }
    out.emplace_back("undergrowth_shades", undergrowthShades ? "true" : "false");
    for (const auto& f : forestFloorParamFields()) out.emplace_back(f.key, paramText(f, *this, kRecordDigits));
    return out;
}

std::vector<h5::NamedAttr> ForestFloorParams::asAttributes() const {
    std::vector<h5::NamedAttr> out;
    for (std::size_t f = 0; f < kFactorCount; ++f) {
        const std::string key = std::string("grass_") + kFactors[f].key;
        out.push_back({key + "_c", grass[f].c});
        out.push_back({key + "_r", grass[f].r});
    }
    out.push_back({"undergrowth_shades", undergrowthShades});
    for (const auto& f : forestFloorParamFields()) out.push_back(paramAttr(f, *this));
    return out;
}

ForestFloor computeForestFloor(const FactorGrids& features, const std::vector<Plant>& canopy,
                               const std::vector<Plant>& undergrowth, const Biome& biome,
                               const ForestFloorParams& params) {
    params.validate();
    const Grid<float>& g = features.geometry();
    for (const auto* other = features.maps.data() + 1; other != features.maps.data() + kFactorCount; ++other)
        if (!other->sameGeometry(g)) throw ValidationError("forest floor: the annual abiotic maps differ in geometry");
    ForestFloor out;
    out.suitability = Grid<float>::like(g, 0.0f);
    out.cumulativeAlpha = Grid<float>::like(g, 0.0f);
    Grid<float> transmission = Grid<float>::like(g, 1.0f);
    const int w = g.width(), h = g.height();
    const VigourShape& shape = biome.vigour;

#pragma omp parallel for schedule(static)
    for (int iy = 0; iy < h; ++iy)
        for (int ix = 0; ix < w; ++ix) {
            const double f = minResponse(shape, params.grass, features.at(ix, iy));
            out.suitability(ix, iy) = static_cast<float>(std::clamp(f, 0.0, 1.0));
        }

    // Crowns, canopy first then undergrowth, drawn by bands of rows: each band by one thread,
    // plants in list order, so products and sums do not depend on the thread count.
    std::vector<const Plant*> plants;
    plants.reserve(canopy.size() + (params.undergrowthShades ? undergrowth.size() : 0));
    for (const Plant& p : canopy) plants.push_back(&p);
    if (params.undergrowthShades)
        for (const Plant& p : undergrowth) plants.push_back(&p);
    for (const Plant* p : plants)
        if (p->speciesId < 0 || static_cast<std::size_t>(p->speciesId) >= biome.species.size())
            throw ValidationError("forest floor: a plant has species id " + std::to_string(p->speciesId) +
                                  ", not a species of biome '" + biome.name + "'");
    constexpr int kBandRows = 16;
    const int nBands = (h + kBandRows - 1) / kBandRows;
    std::vector<std::vector<std::uint32_t>> band(static_cast<std::size_t>(std::max(nBands, 0)));
    const double cs = g.cellSizeM();
    for (std::size_t i = 0; i < plants.size(); ++i) {
        const Plant& p = *plants[i];
        const int y0 = std::max(0, static_cast<int>(std::floor((p.yM - p.crownRadiusM - g.originY()) / cs - 0.5)));
        const int y1 = std::min(h - 1, static_cast<int>(std::ceil((p.yM + p.crownRadiusM - g.originY()) / cs - 0.5)));
        for (int b = y0 / kBandRows; b <= y1 / kBandRows && y0 <= y1; ++b)
            band[static_cast<std::size_t>(b)].push_back(static_cast<std::uint32_t>(i));
    }
#pragma omp parallel for schedule(dynamic, 1)
    for (int b = 0; b < nBands; ++b) {
        const int by0 = b * kBandRows, by1 = std::min(h - 1, by0 + kBandRows - 1);
        for (std::uint32_t i : band[static_cast<std::size_t>(b)]) {
            const Plant& p = *plants[i];
            const double r = p.crownRadiusM, r2 = r * r;
            const float alpha = static_cast<float>(biome.species[static_cast<std::size_t>(p.speciesId)].alpha);
            const int x0 = std::max(0, static_cast<int>(std::floor((p.xM - r - g.originX()) / cs - 0.5)));
            const int x1 = std::min(w - 1, static_cast<int>(std::ceil((p.xM + r - g.originX()) / cs - 0.5)));
            const int y0 = std::max(by0, static_cast<int>(std::floor((p.yM - r - g.originY()) / cs - 0.5)));
            const int y1 = std::min(by1, static_cast<int>(std::ceil((p.yM + r - g.originY()) / cs - 0.5)));
            for (int iy = y0; iy <= y1; ++iy) {
                const double dy = g.cellCentreY(iy) - p.yM;
                for (int ix = x0; ix <= x1; ++ix) {
                    const double dx = g.cellCentreX(ix) - p.xM;
                    if (dx * dx + dy * dy <= r2) {
                        transmission(ix, iy) *= 1.0f - alpha;
                        out.cumulativeAlpha(ix, iy) += alpha;
                    }
                }
            }
        }
    }
    out.grass = Grid<float>::like(g, 0.0f);
    out.litter = Grid<float>::like(g, 0.0f);
    const float full = static_cast<float>(params.litterFullAlpha);
    for (std::size_t i = 0; i < out.grass.size(); ++i) {
        out.grass.data()[i] = out.suitability.data()[i] * transmission.data()[i];
        out.litter.data()[i] = std::min(1.0f, out.cumulativeAlpha.data()[i] / full);
    }
    return out;
}

}  // namespace eco::synth
