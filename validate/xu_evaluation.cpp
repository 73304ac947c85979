#include "xu_evaluation.h"

#include "error.h"
#include "fidelity.h"
#include "rng.h"
#include "text_format.h"

namespace eco::validate {

namespace {
constexpr std::uint64_t kPatchStream = 0x5855504154434845ull;  // "XUPATCHE"
}

XuIndices xuIndices(const std::vector<double>& x, const std::vector<double>& y, const RectWindow& window,
                    const DistanceBins& bins) {
    PointPattern p;
    p.typeNames = {"all"};
    for (std::size_t i = 0; i < x.size(); ++i)
        if (window.contains(x[i], y[i])) {
            p.x.push_back(x[i]);
            p.y.push_back(y[i]);
            p.type.push_back(0);
        }
    PcfOptions opt;
    opt.bins = bins;
    opt.isotropic = false;
    const PairSums sums = countPairs(p, window, opt);
    const std::vector<double> l = ripleyLMinusR(sums);
    double m = 0;
    for (double v : l) m += v;
    XuIndices out;
    out.densityPerM2 = static_cast<double>(p.size()) / window.areaM2();
    out.ripleyIndexM = l.empty() ? 0.0 : m / static_cast<double>(l.size());
    return out;
}

XuEvaluation evaluateXu(const std::vector<double>& ex, const std::vector<double>& ey, const RectWindow& exemplarWindow,
                        const std::vector<double>& sx, const std::vector<double>& sy, const RectWindow& synthWindow,
                        const DistanceBins& bins, const std::vector<int>& factors, int patches, std::uint64_t seed) {
    if (patches < 1) throw ValidationError("Xu evaluation: patches must be >= 1, got " + std::to_string(patches));
    XuEvaluation out;
    out.exemplar = xuIndices(ex, ey, exemplarWindow, bins);
    for (const int k : factors) {
        const double w = k * exemplarWindow.widthM(), h = k * exemplarWindow.heightM();
        if (k < 1 || w > synthWindow.widthM() || h > synthWindow.heightM())
            throw ValidationError("Xu evaluation: a " + std::to_string(k) + " x " + std::to_string(k) +
                                  " patch of the exemplar's area does not fit in the synthesized window (" +
                                  formatNumber(synthWindow.widthM()) + " x " + formatNumber(synthWindow.heightM()) + " m)");
        XuEnlargement e;
        e.factor = k;
        e.patches = patches;
        for (int p = 0; p < patches; ++p) {
            RandomStream rs(seed, mixStream(kPatchStream, static_cast<std::uint64_t>(k)), static_cast<std::uint64_t>(p));
            const double x0 = synthWindow.x0 + rs.uniform() * (synthWindow.widthM() - w);
            const double y0 = synthWindow.y0 + rs.uniform() * (synthWindow.heightM() - h);
            const XuIndices idx = xuIndices(sx, sy, RectWindow{x0, y0, x0 + w, y0 + h}, bins);
            e.mean.densityPerM2 += idx.densityPerM2 / patches;
            e.mean.ripleyIndexM += idx.ripleyIndexM / patches;
        }
        e.pctDevDensity = pctDev(e.mean.densityPerM2, out.exemplar.densityPerM2);
        e.pctDevRipley = pctDev(e.mean.ripleyIndexM, out.exemplar.ripleyIndexM);
        out.meanPctDevDensity += e.pctDevDensity / static_cast<double>(factors.size());
        out.meanPctDevRipley += e.pctDevRipley / static_cast<double>(factors.size());
        out.enlargements.push_back(e);
    }
    return out;
}

}  // namespace eco::validate
