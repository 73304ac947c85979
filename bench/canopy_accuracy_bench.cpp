// Accuracy of canopy tree detection on CHMs that look like lidar (issue 25): the canopy
// placer against a variable-window-filter baseline, on CHMs made from known trees.
//
// Scenes: trees from core's generateChm (a Dense / Sparse sketch, heights 4..40 m, crown
// radius by the Douglas-Fir allometry), each rendered with a crown shape of its own:
// z = h - D (d / r)^p inside its disc, depth D = r x U(1, 2) (conifers deeper than wide) and
// shape p = U(1.2, 2.5) (cones to domes), not the placer's sphere; the CHM is the maximum
// over trees, plus Gaussian noise (0.15 m), ground returns a little below 0 (down to
// -0.4 m) and nodata holes (1 % of the cells, in clumps), as lidar CHMs come. Gaps are
// filled by the CHM reader's default rule (core/terrain_io.h readChm).
//
// Truth: the tree tops (h >= 3 m) visible from above (the noise-free CHM at the apex is the
// tree's own height within 0.3 m). A detection matches a tree top when they are the nearest
// unmatched pair within 1 m (greedy over all pairs by distance). Precision = matched /
// detections, recall = matched / tree tops; detections below 3 m are not counted.
//
// Methods: the placer with its defaults; the placer's seeding alone (--max-iterations 0);
// a variable window filter (Popescu & Wynne 2004): a cell is a tree top when, on the CHM
// smoothed by a 3 x 3 Gaussian, no cell within k x crown radius(h) is higher (ties to the
// lower index), k the best of 0.2 .. 1.0 on each scene (a strong baseline). The placer runs
// with its defaults (apex trees anchored, the best state kept, trees added at residual apices,
// added trees supported by CHM cells no crown explains, seeds without a saddle between them
// merged, added trees snapped onto the CHM apex of their visible cells, then fitted as the
// sphere that best explains what the other crowns leave, hidden apices dropped) and with the
// paper's rules (all seven off), as it was before issue 25.
//
// Usage: bench_canopy_accuracy [OUT (default bench/results/canopy_accuracy.txt)] [SIZE (256)]
//        [KEY=VALUE ...]  (canopy parameters of the "defaults" row, e.g. ring_samples=0; and
//        scene_seed_offset=N: the four scenes made with seeds 1+N .. 4+N instead of 1 .. 4,
//        to check a rule on other CHMs than the ones it was measured on)
#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "bench_common.h"
#include "biome.h"
#include "canopy_placer.h"
#include "eco_version.h"
#include "generate.h"
#include "rng.h"
#include "terrain_io.h"

namespace {

using namespace eco::bench;
using Clock = std::chrono::steady_clock;

struct Top {
    double x, y, h;
};

struct Scene {
    eco::Grid<float> chm;      ///< as the placer gets it (noise, negatives, gaps filled)
    std::vector<Top> tops;     ///< visible tree tops >= 3 m
    std::vector<Top> all;      ///< every generated tree (hidden tops included)
    std::size_t trees = 0;     ///< all generated trees
    std::int64_t gaps = 0, negatives = 0;
};

Scene makeScene(int n, std::uint64_t seed, double denseSpacingM, bool spheres = false) {
    eco::TerrainGenParams tp;
    tp.width = tp.height = n;
    tp.seed = seed;
    const eco::Grid<float> terrain = eco::generateTerrain(tp);
    eco::SketchParams sk;
    sk.seed = seed;
    const eco::Grid<std::int32_t> sketch = eco::generateDensitySketch(terrain, sk);
    eco::ChmGenParams cp;
    cp.seed = seed;
    cp.denseSpacingM = denseSpacingM;
    cp.sparseSpacingM = denseSpacingM * 2.2;
    cp.minHeightM = spheres ? 3.5 : 4;
    cp.maxHeightM = spheres ? 11 : 40;
    std::vector<eco::GeneratedTree> trees;
    const eco::Grid<float> sphereChm = eco::generateChm(sketch, cp, trees);
    Scene s;
    s.trees = trees.size();
    for (const auto& t : trees) s.all.push_back({t.x, t.y, t.heightM});
    eco::Grid<float> clean = eco::Grid<float>::like(terrain, 0.0f);
    const double cs = clean.cellSizeM();
    std::vector<double> depth(trees.size()), shape(trees.size());
    for (std::size_t i = 0; i < trees.size(); ++i) {
        eco::RandomStream rs(seed, eco::mixStream(0x4c49444152ull, i), 0);
        depth[i] = trees[i].crownRadiusM * (1.0 + rs.uniform());
        shape[i] = 1.2 + 1.3 * rs.uniform();
    }
    if (spheres) {
        // The benchmarks' stand-in CHM as it is (spheres of the placer's own model, no noise).
        s.chm = sphereChm;
        for (const eco::GeneratedTree& t : trees) {
            const int ix = sphereChm.cellX(t.x), iy = sphereChm.cellY(t.y);
            if (t.heightM < 3 || !sphereChm.inside(ix, iy)) continue;
            const double d = std::hypot(sphereChm.cellCentreX(ix) - t.x, sphereChm.cellCentreY(iy) - t.y);
            const double own = t.heightM - t.crownRadiusM + std::sqrt(std::max(0.0, t.crownRadiusM * t.crownRadiusM - d * d));
            if (sphereChm(ix, iy) <= own + 0.3) s.tops.push_back({t.x, t.y, t.heightM});
        }
        return s;
    }
    for (std::size_t i = 0; i < trees.size(); ++i) {
        const eco::GeneratedTree& t = trees[i];
        const double r = t.crownRadiusM;
        const int x0 = std::max(0, clean.cellX(t.x - r)), x1 = std::min(n - 1, clean.cellX(t.x + r));
        const int y0 = std::max(0, clean.cellY(t.y - r)), y1 = std::min(n - 1, clean.cellY(t.y + r));
        for (int iy = y0; iy <= y1; ++iy)
            for (int ix = x0; ix <= x1; ++ix) {
                const double d = std::hypot(clean.cellCentreX(ix) - t.x, clean.cellCentreY(iy) - t.y);
                if (d >= r) continue;
                const double z = std::max(0.0, t.heightM - depth[i] * std::pow(d / r, shape[i]));
                clean(ix, iy) = std::max(clean(ix, iy), static_cast<float>(z));
            }
    }
    for (std::size_t i = 0; i < trees.size(); ++i) {
        const eco::GeneratedTree& t = trees[i];
        if (t.heightM < 3) continue;
        const int ix = clean.cellX(t.x), iy = clean.cellY(t.y);
        if (!clean.inside(ix, iy)) continue;
        // Visible: no other crown above this tree's own surface at its apex cell by more than 0.3 m.
        const double d = std::hypot(clean.cellCentreX(ix) - t.x, clean.cellCentreY(iy) - t.y);
        const double own = t.heightM - depth[i] * std::pow(std::min(1.0, d / t.crownRadiusM), shape[i]);
        if (clean(ix, iy) <= own + 0.3) s.tops.push_back({t.x, t.y, t.heightM});
    }
    // Lidar: noise, ground a little below 0, clumps of nodata (NaN) filled as readChm does.
    s.chm = clean;
    eco::RandomStream noise(seed, 0x4e4f495345ull, 0);
    for (int iy = 0; iy < n; ++iy)
        for (int ix = 0; ix < n; ++ix) {
            float& v = s.chm(ix, iy);
            const double u1 = 1.0 - noise.uniform(), u2 = noise.uniform();
            const double g = std::sqrt(-2 * std::log(u1)) * std::cos(6.283185307179586 * u2);
            v = v > 0 ? static_cast<float>(v + 0.15 * g) : static_cast<float>(-0.4 * noise.uniform() * (noise.uniform() < 0.3));
        }
    const int clumps = n * n / 400;  // 1 % of the cells in clumps of about 4 cells
    for (int k = 0; k < clumps; ++k) {
        const int cx = static_cast<int>(noise.below(static_cast<std::uint32_t>(n))), cy = static_cast<int>(noise.below(static_cast<std::uint32_t>(n)));
        for (int j = 0; j < 4; ++j) {
            const int x = std::clamp(cx + static_cast<int>(noise.below(3)) - 1, 0, n - 1);
            const int y = std::clamp(cy + static_cast<int>(noise.below(3)) - 1, 0, n - 1);
            s.chm(x, y) = std::numeric_limits<float>::quiet_NaN();
        }
    }
    // The reader's rules: gaps filled from neighbours, negatives clamped (written and read
    // back through an .asc with NODATA_value, as a user's file would be).
    const std::string tmp = "/tmp/eco_canopy_accuracy_" + std::to_string(seed) + ".asc";
    eco::Grid<float> withNodata = s.chm;
    for (float& v : withNodata.data())
        if (std::isnan(v)) v = -9999.0f;
    {
        std::FILE* f = std::fopen(tmp.c_str(), "w");
        std::fprintf(f, "ncols %d\nnrows %d\nxllcorner 0\nyllcorner 0\ncellsize %.17g\nNODATA_value -9999\n", n, n, cs);
        for (int row = n - 1; row >= 0; --row) {
            for (int ix = 0; ix < n; ++ix) std::fprintf(f, "%.9g ", withNodata(ix, row));
            std::fputc('\n', f);
        }
        std::fclose(f);
    }
    const eco::ChmRead read = eco::readChm(tmp);
    std::remove(tmp.c_str());
    s.chm = read.chm;
    s.gaps = read.nodataCells;
    s.negatives = read.negativeCells;
    return s;
}

struct Score {
    std::size_t detections = 0, matched = 0;
    double precision = 0, recall = 0, f1 = 0, heightBiasM = 0;
};

Score score(const std::vector<Top>& tops, const std::vector<Top>& found) {
    std::vector<Top> det;
    for (const Top& t : found)
        if (t.h >= 3) det.push_back(t);
    struct Pair {
        double d;
        std::size_t a, b;
    };
    std::vector<Pair> pairs;
    // Pairs within 1 m through a bucket grid of the detections.
    const double bucket = 1.0;
    double maxX = 0, maxY = 0;
    for (const Top& t : det) maxX = std::max(maxX, t.x), maxY = std::max(maxY, t.y);
    for (const Top& t : tops) maxX = std::max(maxX, t.x), maxY = std::max(maxY, t.y);
    const int nx = static_cast<int>(maxX / bucket) + 2, ny = static_cast<int>(maxY / bucket) + 2;
    std::vector<std::vector<std::size_t>> grid(static_cast<std::size_t>(nx) * static_cast<std::size_t>(ny));
    auto cell = [&](double x, double y) {
        return static_cast<std::size_t>(std::clamp(static_cast<int>(y / bucket), 0, ny - 1)) * static_cast<std::size_t>(nx) +
               static_cast<std::size_t>(std::clamp(static_cast<int>(x / bucket), 0, nx - 1));
    };
    for (std::size_t j = 0; j < det.size(); ++j) grid[cell(det[j].x, det[j].y)].push_back(j);
    for (std::size_t i = 0; i < tops.size(); ++i) {
        const int bx = static_cast<int>(tops[i].x / bucket), by = static_cast<int>(tops[i].y / bucket);
        for (int y = by - 1; y <= by + 1; ++y)
            for (int x = bx - 1; x <= bx + 1; ++x) {
                if (x < 0 || y < 0 || x >= nx || y >= ny) continue;
                for (std::size_t j : grid[static_cast<std::size_t>(y) * static_cast<std::size_t>(nx) + static_cast<std::size_t>(x)]) {
                    const double d = std::hypot(tops[i].x - det[j].x, tops[i].y - det[j].y);
                    if (d <= 1.0) pairs.push_back({d, i, j});
                }
            }
    }
    std::sort(pairs.begin(), pairs.end(), [](const Pair& a, const Pair& b) { return a.d != b.d ? a.d < b.d : (a.a != b.a ? a.a < b.a : a.b < b.b); });
    std::vector<char> usedA(tops.size(), 0), usedB(det.size(), 0);
    Score s;
    double bias = 0;
    for (const Pair& p : pairs) {
        if (usedA[p.a] || usedB[p.b]) continue;
        usedA[p.a] = usedB[p.b] = 1;
        ++s.matched;
        bias += det[p.b].h - tops[p.a].h;
    }
    s.detections = det.size();
    s.precision = det.empty() ? 0 : double(s.matched) / double(det.size());
    s.recall = tops.empty() ? 0 : double(s.matched) / double(tops.size());
    s.f1 = s.precision + s.recall > 0 ? 2 * s.precision * s.recall / (s.precision + s.recall) : 0;
    s.heightBiasM = s.matched > 0 ? bias / double(s.matched) : 0;
    return s;
}

/// Variable window filter on the 3 x 3 Gaussian-smoothed CHM: window radius k x r(h).
std::vector<Top> variableWindowFilter(const eco::Grid<float>& chm, const eco::Allometry& allometry, double k) {
    const int w = chm.width(), h = chm.height();
    eco::Grid<float> sm = eco::Grid<float>::like(chm, 0.0f);
    const double kern[3] = {0.25, 0.5, 0.25};
    for (int iy = 0; iy < h; ++iy)
        for (int ix = 0; ix < w; ++ix) {
            double acc = 0, wt = 0;
            for (int dy = -1; dy <= 1; ++dy)
                for (int dx = -1; dx <= 1; ++dx) {
                    const int x = ix + dx, y = iy + dy;
                    if (x < 0 || y < 0 || x >= w || y >= h) continue;
                    const double c = kern[dx + 1] * kern[dy + 1];
                    acc += c * chm(x, y);
                    wt += c;
                }
            sm(ix, iy) = static_cast<float>(acc / wt);
        }
    std::vector<Top> out;
    const double cs = chm.cellSizeM();
    for (int iy = 0; iy < h; ++iy)
        for (int ix = 0; ix < w; ++ix) {
            const float v = sm(ix, iy);
            if (v < 3) continue;
            const double rad = std::max(cs, k * allometry.crownRadiusM(v));
            const int rc = static_cast<int>(std::ceil(rad / cs));
            bool top = true;
            for (int dy = -rc; dy <= rc && top; ++dy)
                for (int dx = -rc; dx <= rc; ++dx) {
                    if (dx == 0 && dy == 0) continue;
                    const int x = ix + dx, y = iy + dy;
                    if (x < 0 || y < 0 || x >= w || y >= h || (dx * dx + dy * dy) * cs * cs > rad * rad) continue;
                    const float u = sm(x, y);
                    if (u > v || (u == v && (dy < 0 || (dy == 0 && dx < 0)))) {
                        top = false;
                        break;
                    }
                }
            if (top) out.push_back({chm.cellCentreX(ix), chm.cellCentreY(iy), chm(ix, iy)});
        }
    return out;
}

std::vector<Top> placerTops(const eco::synth::CanopyResult& r) {
    std::vector<Top> t;
    for (const eco::Plant& p : r.trees) t.push_back({p.xM, p.yM, p.heightM});
    return t;
}

}  // namespace

int main(int argc, char** argv) {
    if (eco::bench::wantsUsage(argc, argv, "usage: bench_canopy_accuracy [OUT [SIZE [KEY=VALUE ...]]]\nPrecision and recall of tree tops on lidar-like CHMs of SIZE x SIZE cells (default 256): the canopy placer against a variable-window filter; writes OUT (default bench/results/canopy_accuracy.txt). KEY=VALUE pairs (canopy parameters, docs/canopy.md) change the placer's first row; scene_seed_offset=N makes the scenes with seeds 1+N .. 4+N.\n")) return 0;
    const std::string outPath = argc > 1 ? argv[1] : "bench/results/canopy_accuracy.txt";
    const int n = argc > 2 ? std::max(32, std::atoi(argv[2])) : 256;
    std::ostringstream report;
    try {
        eco::synth::CanopyParams tuned;
        std::string overrides;
        std::uint64_t sceneSeedOffset = 0;
        for (int a = 3; a < argc; ++a) {
            const std::string kv = argv[a];
            const eco::bench::KeyValue p = eco::bench::parseKeyValue(kv);
            if (p.key == "scene_seed_offset") {
                if (!(p.value >= 0 && p.value <= 1e9 && p.value == static_cast<double>(static_cast<std::uint64_t>(p.value))))
                    throw std::runtime_error("argument '" + kv + "': scene_seed_offset must be a whole number >= 0");
                sceneSeedOffset = static_cast<std::uint64_t>(p.value);
                continue;
            }
            eco::synth::setCanopyParam(tuned, p.key, p.value);
            overrides += (overrides.empty() ? "" : ", ") + kv;
        }
        eco::synth::validateCanopyParams(tuned);
        const eco::Biome biome = eco::defaultBiome();
        int douglas = -1;
        for (const eco::Species& s : biome.species)
            if (s.name == "Douglas-Fir") douglas = s.id;
        if (douglas < 0) throw std::runtime_error("no Douglas-Fir in the default biome");
        const eco::Allometry& allo = biome.species[static_cast<std::size_t>(douglas)].allometry;
        report << "canopy detection accuracy on lidar-like CHMs (eco " << ECO_VERSION_STRING << "), " << n << " x " << n
               << " cells of 0.914 m, OpenMP threads " << omp_get_max_threads() << "\n"
               << "match: one to one within 1 m; tree tops = visible apices >= 3 m; detections >= 3 m\n\n";
        std::cout << report.str() << std::flush;
        for (const auto& [seed0, spacing] : std::vector<std::pair<std::uint64_t, double>>{{1, 5.0}, {2, 7.0}, {3, 10.0}, {4, 2.0}}) {
            const std::uint64_t seed = seed0 + sceneSeedOffset;
            const bool spheres = spacing < 3;  // the last: bench_canopy's CHM (spheres, 3.5-11 m, 2 m spacing)
            const Scene sc = makeScene(n, seed, spacing, spheres);
            std::ostringstream sec;
            char line[600];
            std::snprintf(line, sizeof line,
                          "scene seed %llu, dense spacing %.0f m%s: %zu trees, %zu visible tops >= 3 m; %lld nodata cells filled, "
                          "%lld negative cells clamped\n",
                          static_cast<unsigned long long>(seed), spacing, spheres ? " (bench_canopy's sphere CHM, no noise)" : "", sc.trees, sc.tops.size(), static_cast<long long>(sc.gaps),
                          static_cast<long long>(sc.negatives));
            sec << line;
            const eco::Grid<float> terrain = eco::Grid<float>::like(sc.chm, 0.0f);
            eco::Grid<std::int32_t> species = eco::Grid<std::int32_t>::like(sc.chm, douglas);
            auto row = [&](const char* what, const Score& s, double seconds, const eco::IterationStats* st) {
                char row_[600];
                std::snprintf(row_, sizeof row_, "  %-34s precision %.3f  recall %.3f  F1 %.3f  (%zu detections, %zu matched, height bias %+.2f m)",
                              what, s.precision, s.recall, s.f1, s.detections, s.matched, s.heightBiasM);
                sec << row_;
                if (st != nullptr) {
                    std::snprintf(line, sizeof line, "  coverage %.4f RMSE %.2f m", st->coverage, st->rmseM);
                    sec << line;
                }
                std::snprintf(line, sizeof line, "  %.3f s\n", seconds);
                sec << line;
            };
            eco::synth::CanopyParams p = tuned;
            auto t0 = Clock::now();
            const eco::synth::CanopyResult full = eco::synth::placeCanopy(sc.chm, terrain, species, biome, p);
            const std::string first = overrides.empty() ? "canopy placer (defaults)" : "placer (" + overrides + ")";
            row(first.c_str(), score(sc.tops, placerTops(full)), std::chrono::duration<double>(Clock::now() - t0).count(), &full.final);
            {
                // Where the placer's detections are: within 1 m of a visible top, else within
                // 1 m of a tree whose top is hidden, else 1-2 m from a visible top, else none.
                std::size_t nearTop = 0, nearHidden = 0, offset = 0, other = 0;
                for (const eco::Plant& pl : full.trees) {
                    if (pl.heightM < 3) continue;
                    double dTop = 1e300, dAny = 1e300;
                    for (const Top& t : sc.tops) dTop = std::min(dTop, std::hypot(t.x - pl.xM, t.y - pl.yM));
                    for (const Top& t : sc.all) dAny = std::min(dAny, std::hypot(t.x - pl.xM, t.y - pl.yM));
                    if (dTop <= 1) ++nearTop;
                    else if (dAny <= 1) ++nearHidden;
                    else if (dTop <= 2) ++offset;
                    else ++other;
                }
                std::snprintf(line, sizeof line,
                              "    its detections: %zu within 1 m of a visible top, %zu within 1 m of a tree with a hidden top, "
                              "%zu 1-2 m from a visible top, %zu elsewhere; %zu seeds merged, %zu hidden apices not output, "
                              "%zu added trees moved onto their apex, %zu hidden by the crown fit (margin %.2f m)\n",
                              nearTop, nearHidden, offset, other, full.seedsMerged, full.hiddenApexTrees, full.apexSnapped,
                              full.crownFitHidden, full.crownFitHiddenMarginM);
                sec << line;
            }
            eco::synth::CanopyParams paper;
            paper.anchorApexTrees = 0;
            paper.keepBestState = 0;
            paper.residualApices = 0;
            paper.supportFraction = 0;
            paper.seedMergeSaddleM = 0;
            paper.apexSnapRadiusFraction = 0;
            paper.crownFitPasses = 0;
            t0 = Clock::now();
            const eco::synth::CanopyResult old = eco::synth::placeCanopy(sc.chm, terrain, species, biome, paper);
            row("placer, paper's rules (before)", score(sc.tops, placerTops(old)), std::chrono::duration<double>(Clock::now() - t0).count(), &old.final);
            p = eco::synth::CanopyParams{};
            p.maxIterations = 0;
            t0 = Clock::now();
            const eco::synth::CanopyResult seeds = eco::synth::placeCanopy(sc.chm, terrain, species, biome, p);
            row("canopy placer, seeding only", score(sc.tops, placerTops(seeds)), std::chrono::duration<double>(Clock::now() - t0).count(), &seeds.final);
            Score best;
            double bestK = 0, bestT = 0;
            for (double k : {0.2, 0.3, 0.4, 0.6, 0.8, 1.0}) {
                t0 = Clock::now();
                const Score s = score(sc.tops, variableWindowFilter(sc.chm, allo, k));
                const double t = std::chrono::duration<double>(Clock::now() - t0).count();
                if (s.f1 > best.f1) best = s, bestK = k, bestT = t;
            }
            std::snprintf(line, sizeof line, "variable window filter, k = %.1f", bestK);
            row(line, best, bestT, nullptr);
            std::cout << sec.str() << std::flush;
            report << sec.str();
        }
        writeReport(outPath, report.str());
    } catch (const std::exception& e) {
        std::cerr << "bench_canopy_accuracy: " << e.what() << "\n";
        return 1;
    }
    return 0;
}
