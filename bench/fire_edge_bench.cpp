// Gap dynamics at the edges of fires in the monthly model (issue 30 item 3;
// docs/disturbance.md "Gap dynamics at fire edges"): the benchmark hectare, N partial fires
// (one per run seed: the first N seeds whose fire burns 20 - 60 % of the area) in August of
// year F, and the undergrowth density (plants per m2) and mean height after each in bands by
// distance to its burn's boundary (inside the burn, its edge on either side, outside),
// against the same run (seed) without the fire in the same bands; mean and 95 % interval
// (Student t) over the N fires. The burn mask is sim::fireBurntCells on the ground the
// simulator uses (the abiotics cells covering the area, August's moisture), to choose the
// seeds before running; the run's recorded mask (the simulation file's /disturbance/mask_*) is
// checked to be the same cells. A measurement, not a speed benchmark: writes
// bench/results/fire_edge.txt (or --out).
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "atomic_file.h"
#include "bench_common.h"
#include "demo_scene.h"
#include "disturbance.h"
#include "simulator.h"

using namespace eco;
using namespace eco::sim;

namespace {

// The simulator's event ground (Simulation::Impl::disturb): the abiotics cells covering the area.
DisturbanceSite siteOf(const SimInputs& in, const SimArea& area, int month) {
    return abioticsDisturbanceSite(in.abiotics, in.biome.wind, month, area.x0, area.y0, area.x1, area.y1);
}

// Band of each site cell by distance to the burn's boundary (distance between cell centres
// to the nearest cell of the other kind): 0 inside (burnt, > 6 m), 1 burnt edge (<= 3 m),
// 2 unburnt edge (<= 3 m), 3 outside (unburnt, > 6 m), -1 between or outside the area.
std::vector<int> bands(const Grid<float>& g, const std::vector<std::uint8_t>& burnt, const SimArea& area) {
    const int w = g.width(), h = g.height();
    const double cs = g.cellSizeM();
    const int reach = static_cast<int>(std::ceil(6.0 / cs)) + 1;
    std::vector<int> out(burnt.size(), -1);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const double cx = g.cellCentreX(x), cy = g.cellCentreY(y);
            if (cx < area.x0 || cx >= area.x1 || cy < area.y0 || cy >= area.y1) continue;
            const std::uint8_t mine = burnt[g.index(x, y)];
            double best = 1e30;
            for (int dy = -reach; dy <= reach; ++dy)
                for (int dx = -reach; dx <= reach; ++dx) {
                    const int nx = x + dx, ny = y + dy;
                    if (nx < 0 || ny < 0 || nx >= w || ny >= h || burnt[g.index(nx, ny)] == mine) continue;
                    best = std::min(best, std::hypot(dx * cs, dy * cs));
                }
            if (mine) out[g.index(x, y)] = best > 6.0 ? 0 : best <= 3.0 ? 1 : -1;
            else out[g.index(x, y)] = best > 6.0 ? 3 : best <= 3.0 ? 2 : -1;
        }
    return out;
}

struct BandStats {
    double count[4] = {0, 0, 0, 0}, height[4] = {0, 0, 0, 0};
};

BandStats measure(const Simulation& sim, const Grid<float>& g, const std::vector<int>& band) {
    BandStats b;
    for (const UndergrowthPlant& p : sim.plants()) {
        const int cx = g.cellX(p.xM), cy = g.cellY(p.yM);
        if (!g.inside(cx, cy)) continue;
        const int k = band[g.index(cx, cy)];
        if (k < 0) continue;
        b.count[k] += 1;
        b.height[k] += p.heightM;
    }
    return b;
}

// Two-sided 95 % Student t quantile for `df` degrees of freedom.
double t975(int df) {
    static const double kT[] = {0,     12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262, 2.228,
                                2.201, 2.179,  2.160, 2.145, 2.131, 2.120, 2.110, 2.101, 2.093, 2.086};
    return df >= 1 && df <= 20 ? kT[df] : (df <= 30 ? 2.05 : 1.96);
}

// Mean and half-width of the 95 % interval of the mean.
std::pair<double, double> meanCi(const std::vector<double>& v) {
    const double n = static_cast<double>(v.size());
    double m = 0;
    for (double x : v) m += x;
    m /= n;
    if (v.size() < 2) return {m, 0.0};
    double ss = 0;
    for (double x : v) ss += (x - m) * (x - m);
    return {m, t975(static_cast<int>(v.size()) - 1) * std::sqrt(ss / (n - 1) / n)};
}

std::string fmtCi(const std::vector<double>& v, int digits) {
    const auto [m, h] = meanCi(v);
    char b[64];
    std::snprintf(b, sizeof b, "%.*f +- %.*f", digits, m, digits, h);
    return b;
}

}  // namespace

int main(int argc, char** argv) {
    std::string outPath = "bench/results/fire_edge.txt";
    int fireYear = 20, fires = 8;
    double spread = 0.45;
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        auto next = [&]() -> std::string {
            if (i + 1 >= argc) {
                std::fprintf(stderr, "bench_fire_edge: %s needs a value\n", a.c_str());
                std::exit(2);
            }
            return argv[++i];
        };
        if (a == "--help" || a == "-h") {
            std::printf(
                "bench_fire_edge [--fires N] [--fire-year F] [--spread P] [--out FILE]\n"
                "  Undergrowth density and mean height at the edges of N partial fires (default 8) in the\n"
                "  monthly model (the benchmark hectare; a fire of spread probability P, default 0.45, in\n"
                "  August of year F, default 20; the first N run seeds whose fire burns 20 - 60 %% of the\n"
                "  area), in bands by distance to each burn's boundary, 0, 1, 2, 5 and 10 years after,\n"
                "  against the same seed's run without the fire: mean and 95 %% interval over the fires.\n"
                "  About a minute of 2 threads per fire. Writes FILE (default bench/results/fire_edge.txt).\n");
            return 0;
        }
        if (a == "--fire-year") fireYear = std::atoi(next().c_str());
        else if (a == "--spread") spread = std::atof(next().c_str());
        else if (a == "--fires") fires = std::atoi(next().c_str());
        else if (a == "--out") outPath = next();
        else {
            std::fprintf(stderr, "bench_fire_edge: unknown argument %s (see --help)\n", a.c_str());
            return 2;
        }
    }
    if (fireYear < 1 || !(spread > 0 && spread <= 1) || fires < 1 || fires > 100) {
        std::fprintf(stderr, "bench_fire_edge: --fire-year must be >= 1, --spread in (0, 1], --fires in 1..100\n");
        return 2;
    }
    const auto t0 = bench::Clock::now();
    const Biome biome = defaultBiome();
    DemoSceneParams sp;
    sp.cells = 128;
    sp.seed = 3;
    SimInputs in = makeDemoScene(sp, biome);
    const SimArea area{5, 5, 105, 105};
    in.area = area;
    DisturbanceSettings d;
    d.fire.enabled = true;
    d.fire.timing.forcedYears = {fireYear};
    d.fire.spreadProbability = spread;
    const DisturbanceSite site = siteOf(in, area, d.fire.timing.month);
    const Grid<float>& g = site.elevationM;
    auto burntArea = [&](const std::vector<std::uint8_t>& burnt) {
        double m2 = 0;
        for (int y = 0; y < g.height(); ++y)
            for (int x = 0; x < g.width(); ++x)
                if (burnt[g.index(x, y)]) {
                    const double x0 = g.originX() + x * g.cellSizeM(), y0 = g.originY() + y * g.cellSizeM();
                    const double wx = std::min(x0 + g.cellSizeM(), area.x1) - std::max(x0, area.x0);
                    const double wy = std::min(y0 + g.cellSizeM(), area.y1) - std::max(y0, area.y0);
                    if (wx > 0 && wy > 0) m2 += wx * wy;
                }
        return m2;
    };
    // The first `fires` seeds whose fire is partial.
    struct Fire {
        std::uint64_t seed;
        std::vector<std::uint8_t> burnt;
        double m2, ix, iy;
    };
    std::vector<Fire> chosen;
    std::uint64_t tried = 0;
    for (std::uint64_t s = 1; s <= 2000 && static_cast<int>(chosen.size()) < fires; ++s, ++tried) {
        Fire f{s, {}, 0, 0, 0};
        f.burnt = fireBurntCells(eventsOfYear(d, s, fireYear).at(0), d.fire, site, s, &f.ix, &f.iy);
        f.m2 = burntArea(f.burnt);
        const double share = f.m2 / ((area.x1 - area.x0) * (area.y1 - area.y0));
        if (share >= 0.2 && share <= 0.6) chosen.push_back(std::move(f));
    }
    if (static_cast<int>(chosen.size()) < fires) {
        std::fprintf(stderr, "bench_fire_edge: only %zu seeds of 1..2000 give a fire over 20 - 60 %% of the area at spread %g\n",
                     chosen.size(), spread);
        return 1;
    }
    std::ostringstream rep;
    char line[700];
    std::snprintf(line, sizeof line,
                  "# bench_fire_edge: monthly model, the benchmark hectare (demo scene 128 cells, seed 3, area [5, 105]^2);\n"
                  "# %d fires of spread probability %.2f (other [disturbance.fire] values the defaults: severity 0.9, scorch 2 m)\n"
                  "# in August of year %d, one per run seed: the first %d seeds of %llu tried whose fire burns 20 - 60 %% of the area;\n"
                  "# each against the same seed's run without it. Bands by distance to the burn's boundary: inside (burnt, > 6 m),\n"
                  "# burnt edge (<= 3 m), unburnt edge (<= 3 m), outside (unburnt, > 6 m)\n",
                  fires, spread, fireYear, fires, static_cast<unsigned long long>(tried));
    rep << line;
    rep << "# seed | ignition x, y m | burnt m2 (% of the area) | band areas m2: inside, burnt edge, unburnt edge, outside\n";
    std::fputs(rep.str().c_str(), stdout);

    omp_set_num_threads(std::min(2, omp_get_max_threads()));
    const int after[] = {0, 1, 2, 5, 10};
    constexpr int kAfter = 5;
    const char* names[4] = {"inside", "burnt edge", "unburnt edge", "outside"};
    // Per (years after, band): one value per fire.
    std::vector<double> dens[kAfter][4], ctrl[kAfter][4], ratio[kAfter][4], hf[kAfter][4], hc[kAfter][4];
    std::vector<double> edgeLead[kAfter];  // ratio at the burnt edge minus ratio inside
    // The summary over the fires done so far, written after each fire (a partial result survives
    // an interrupted run; the header says over how many fires).
    auto writeSummary = [&](int done_) {
        std::ostringstream sum;
        sum << rep.str();
        std::snprintf(line, sizeof line, "# mean +- half-width of the 95 %% interval of the mean over the %d fires (Student t, %d df)\n",
                      done_, done_ - 1);
        sum << line;
        sum << "years after | band | plants/m2 with fire | without | ratio | mean height m with fire | without\n";
        for (int ai = 0; ai < kAfter; ++ai)
            for (int k = 0; k < 4; ++k) {
                std::snprintf(line, sizeof line, "%d | %s | %s | %s | %s | %s | %s\n", after[ai], names[k],
                              fmtCi(dens[ai][k], 2).c_str(), fmtCi(ctrl[ai][k], 2).c_str(), fmtCi(ratio[ai][k], 2).c_str(),
                              fmtCi(hf[ai][k], 3).c_str(), fmtCi(hc[ai][k], 3).c_str());
                sum << line;
            }
        sum << "# does the burnt edge recover first? ratio (with / without fire) at the burnt edge minus inside, per fire:\n";
        sum << "years after | edge - inside ratio | fires with the edge ahead\n";
        for (int ai = 0; ai < kAfter; ++ai) {
            int ahead = 0;
            for (double v : edgeLead[ai]) ahead += v > 0 ? 1 : 0;
            std::snprintf(line, sizeof line, "%d | %s | %d of %d\n", after[ai], fmtCi(edgeLead[ai], 3).c_str(), ahead, done_);
            sum << line;
        }
        std::snprintf(line, sizeof line, "# %.0f s wall, 2 threads, load average %.1f at the end\n", bench::secondsSince(t0),
                      bench::loadAverage());
        sum << line;
        std::fputs(sum.str().c_str(), stdout);
        AtomicOutput out(outPath);
        {
            std::ofstream f(out.tempPath());
            f << sum.str();
        }
        out.commit();
    };
    for (const Fire& fi : chosen) {
        const std::vector<int> band = bands(g, fi.burnt, area);
        double bandArea[4] = {0, 0, 0, 0};
        const double cellArea = g.cellSizeM() * g.cellSizeM();
        for (int k : band)
            if (k >= 0) bandArea[k] += cellArea;
        std::snprintf(line, sizeof line, "# %llu | %.1f, %.1f | %.0f (%.0f %%) | %.0f, %.0f, %.0f, %.0f\n",
                      static_cast<unsigned long long>(fi.seed), fi.ix, fi.iy, fi.m2, fi.m2 / 100.0, bandArea[0], bandArea[1],
                      bandArea[2], bandArea[3]);
        rep << line;
        std::fputs(line, stdout);
        std::fflush(stdout);
        Simulation fire(in, SimParams{}, fi.seed), control(in, SimParams{}, fi.seed);
        fire.setDisturbance(d);
        int done = 0;
        for (int ai = 0; ai < kAfter; ++ai) {
            // Census of year F + a: after year F (the fire and its August germination) and a more.
            const int target = fireYear + 1 + after[ai];
            for (; done < target; ++done) {
                fire.stepYear();
                control.stepYear();
            }
            if (ai == 0) {  // the run's recorded mask is the one chosen
                const auto& ev = fire.disturbances();
                std::vector<std::int32_t> cells;
                for (std::size_t c = 0; c < fi.burnt.size(); ++c)
                    if (fi.burnt[c]) cells.push_back(static_cast<std::int32_t>(c));
                if (ev.size() != 1 || ev[0].mask.cells != cells || ev[0].mask.width != g.width() ||
                    std::fabs(ev[0].areaM2 - fi.m2) > 1e-6 * fi.m2) {
                    std::fprintf(stderr, "bench_fire_edge: seed %llu: the simulator's recorded burn mask differs from the chosen one\n",
                                 static_cast<unsigned long long>(fi.seed));
                    return 1;
                }
            }
            const BandStats f = measure(fire, g, band), c = measure(control, g, band);
            double r[4] = {0, 0, 0, 0};
            for (int k = 0; k < 4; ++k) {
                const double df = f.count[k] / bandArea[k], dc = c.count[k] / bandArea[k];
                r[k] = dc > 0 ? df / dc : 0.0;
                dens[ai][k].push_back(df);
                ctrl[ai][k].push_back(dc);
                ratio[ai][k].push_back(r[k]);
                hf[ai][k].push_back(f.count[k] > 0 ? f.height[k] / f.count[k] : 0.0);
                hc[ai][k].push_back(c.count[k] > 0 ? c.height[k] / c.count[k] : 0.0);
            }
            edgeLead[ai].push_back(r[1] - r[0]);
        }
        writeSummary(static_cast<int>(edgeLead[0].size()));
    }
    return 0;
}
