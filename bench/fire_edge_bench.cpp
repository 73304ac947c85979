// Gap dynamics at the edges of a fire in the monthly model (issue 30 item 3;
// docs/disturbance.md "Gap dynamics at fire edges"): the benchmark hectare, a partial fire in
// August of year F, and the undergrowth density (plants per m2) and mean height after it in
// bands by distance to the burn's boundary (inside the burn, its edge on either side,
// outside), against the same run without the fire in the same bands. The burn mask comes from
// sim::fireBurntCells on the ground the simulator uses (the abiotics cells covering the area,
// August's moisture): the same cells the simulator burnt (its recorded area is checked
// against the mask's). A measurement, not a speed benchmark: writes
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

}  // namespace

int main(int argc, char** argv) {
    std::string outPath = "bench/results/fire_edge.txt";
    int fireYear = 20;
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
                "bench_fire_edge [--fire-year F] [--spread P] [--out FILE]\n"
                "  Undergrowth density and mean height at the edges of a partial fire in the monthly model\n"
                "  (the benchmark hectare; a fire of spread probability P, default 0.45, in August of year F,\n"
                "  default 20; the first seed whose fire burns 20 - 60 %% of the area), in bands by distance\n"
                "  to the burn's boundary, 1, 2, 5 and 10 years after, against the run without the fire.\n"
                "  Writes FILE (default bench/results/fire_edge.txt).\n");
            return 0;
        }
        if (a == "--fire-year") fireYear = std::atoi(next().c_str());
        else if (a == "--spread") spread = std::atof(next().c_str());
        else if (a == "--out") outPath = next();
        else {
            std::fprintf(stderr, "bench_fire_edge: unknown argument %s (see --help)\n", a.c_str());
            return 2;
        }
    }
    if (fireYear < 1 || !(spread > 0 && spread <= 1)) {
        std::fprintf(stderr, "bench_fire_edge: --fire-year must be >= 1 and --spread in (0, 1]\n");
        return 2;
    }
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
    // The first seed whose fire is partial.
    std::uint64_t seed = 0;
    std::vector<std::uint8_t> burnt;
    double burntM2 = 0, ix = 0, iy = 0;
    for (std::uint64_t s = 1; s <= 200 && seed == 0; ++s) {
        const auto events = eventsOfYear(d, s, fireYear);
        burnt = fireBurntCells(events.at(0), d.fire, site, s, &ix, &iy);
        burntM2 = 0;
        for (int y = 0; y < g.height(); ++y)
            for (int x = 0; x < g.width(); ++x)
                if (burnt[g.index(x, y)]) {
                    const double x0 = g.originX() + x * g.cellSizeM(), y0 = g.originY() + y * g.cellSizeM();
                    const double wx = std::min(x0 + g.cellSizeM(), area.x1) - std::max(x0, area.x0);
                    const double wy = std::min(y0 + g.cellSizeM(), area.y1) - std::max(y0, area.y0);
                    if (wx > 0 && wy > 0) burntM2 += wx * wy;
                }
        const double share = burntM2 / ((area.x1 - area.x0) * (area.y1 - area.y0));
        if (share >= 0.2 && share <= 0.6) seed = s;
    }
    if (seed == 0) {
        std::fprintf(stderr, "bench_fire_edge: no seed in 1..200 gives a fire over 20 - 60 %% of the area at spread %g\n", spread);
        return 1;
    }
    const std::vector<int> band = bands(g, burnt, area);
    double bandArea[4] = {0, 0, 0, 0};
    const double cellArea = g.cellSizeM() * g.cellSizeM();
    for (int k : band)
        if (k >= 0) bandArea[k] += cellArea;

    std::ostringstream rep;
    char line[600];
    std::snprintf(line, sizeof line,
                  "# bench_fire_edge: monthly model, the benchmark hectare (demo scene 128 cells, seed 3, area [5, 105]^2), seed %llu;\n"
                  "# a fire of spread probability %.2f (other [disturbance.fire] values the defaults: severity 0.9, scorch 2 m)\n"
                  "# in August of year %d, ignited at (%.1f, %.1f), burning %.0f m2 (%.0f %% of the area)\n",
                  static_cast<unsigned long long>(seed), spread, fireYear, ix, iy, burntM2, burntM2 / 100.0);
    rep << line;
    std::snprintf(line, sizeof line,
                  "# bands by distance to the burn's boundary: inside (burnt, > 6 m) %.0f m2, burnt edge (<= 3 m) %.0f m2,\n"
                  "# unburnt edge (<= 3 m) %.0f m2, outside (unburnt, > 6 m) %.0f m2\n",
                  bandArea[0], bandArea[1], bandArea[2], bandArea[3]);
    rep << line;
    std::fputs(rep.str().c_str(), stdout);

    omp_set_num_threads(std::min(2, omp_get_max_threads()));
    Simulation fire(in, SimParams{}, seed), control(in, SimParams{}, seed);
    fire.setDisturbance(d);
    const int after[] = {0, 1, 2, 5, 10};
    int done = 0;
    rep << "years after | band | plants/m2 with fire | without | ratio | mean height m with fire | without\n";
    const char* names[4] = {"inside", "burnt edge", "unburnt edge", "outside"};
    for (int a : after) {
        // Census of year F + a: after year F (the fire and its August germination) and a more.
        const int target = fireYear + 1 + a;
        for (; done < target; ++done) {
            fire.stepYear();
            control.stepYear();
        }
        if (a == 0) {
            if (fire.disturbances().size() != 1 || std::fabs(fire.disturbances()[0].areaM2 - burntM2) > 1e-6 * burntM2) {
                std::fprintf(stderr, "bench_fire_edge: the simulator burnt %.1f m2, the mask %.1f m2: the masks differ\n",
                             fire.disturbances().empty() ? 0.0 : fire.disturbances()[0].areaM2, burntM2);
                return 1;
            }
        }
        const BandStats f = measure(fire, g, band), c = measure(control, g, band);
        for (int k = 0; k < 4; ++k) {
            const double df = f.count[k] / bandArea[k], dc = c.count[k] / bandArea[k];
            std::snprintf(line, sizeof line, "%d | %s | %.2f | %.2f | %.2f | %.3f | %.3f\n", a, names[k], df, dc,
                          dc > 0 ? df / dc : 0.0, f.count[k] > 0 ? f.height[k] / f.count[k] : 0.0,
                          c.count[k] > 0 ? c.height[k] / c.count[k] : 0.0);
            rep << line;
            std::fputs(line, stdout);
            std::fflush(stdout);
        }
    }
    AtomicOutput out(outPath);
    {
        std::ofstream f(out.tempPath());
        f << rep.str();
    }
    out.commit();
    return 0;
}
