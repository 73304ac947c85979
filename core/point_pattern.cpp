#include "point_pattern.h"

#include <flann/flann.hpp>
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>

#include "atomic_file.h"
#include "error.h"
#include "memory.h"
#include "text_format.h"
#include "provenance.h"

namespace eco {

namespace {

constexpr double kPi = 3.14159265358979323846;

std::string ppNum(double v) { return formatNumber(v, 10); }

/// Points per chunk of the parallel pair loops. Fixed (never derived from the thread count)
/// so that the chunked floating-point sums, added in chunk order, are bit-identical.
constexpr std::size_t kChunkPoints = 2048;

std::string trimmed(const std::string& s) { return trimmedText(s); }

}  // namespace

void RectWindow::validate(const std::string& what) const {
    if (!std::isfinite(x0) || !std::isfinite(y0) || !std::isfinite(x1) || !std::isfinite(y1) || !(x0 < x1) ||
        !(y0 < y1))
        throw ValidationError(what + ": window " + ppNum(x0) + "," + ppNum(y0) + "," + ppNum(x1) + "," + ppNum(y1) +
                              " must have finite corners with x0 < x1 and y0 < y1");
}

double DistanceBins::annulusAreaM2(int k) const {
    const double lo = loM(k), hi = hiM(k);
    return kPi * (hi * hi - lo * lo);
}

std::vector<double> DistanceBins::edgesM() const {
    std::vector<double> e(static_cast<std::size_t>(count) + 1);
    for (int k = 0; k <= count; ++k) e[static_cast<std::size_t>(k)] = loM(k);
    return e;
}

void DistanceBins::validate(const std::string& what) const {
    if (!(rMaxM > 0.0) || !std::isfinite(rMaxM))
        throw ValidationError(what + ": rmax must be positive and finite, got " + ppNum(rMaxM));
    if (count < 1 || count > 100000)
        throw ValidationError(what + ": number of distance bins must be in 1..100000, got " + std::to_string(count));
}

std::vector<double> SeparationBins::edgesM() const {
    std::vector<double> e(static_cast<std::size_t>(count) + 1);
    for (int k = 0; k <= count; ++k) e[static_cast<std::size_t>(k)] = loM(k);
    return e;
}

void SeparationBins::validate(const std::string& what) const {
    if (!std::isfinite(minM) || !std::isfinite(maxM) || !(minM < maxM))
        throw ValidationError(what + ": separation range " + ppNum(minM) + " .. " + ppNum(maxM) +
                              " m must be finite with min < max");
    if (!(maxM >= 0.0)) throw ValidationError(what + ": separation max must be >= 0 m, got " + ppNum(maxM));
    if (count < 1 || count > 100000)
        throw ValidationError(what + ": number of separation bins must be in 1..100000, got " + std::to_string(count));
}

double isotropicWeight(const RectWindow& w, double x, double y, double r) {
    if (!(r > 0.0)) return 1.0;
    const double ex = std::min(x - w.x0, w.x1 - x);
    const double ey = std::min(y - w.y0, w.y1 - y);
    const bool cutX = ex < r, cutY = ey < r;
    if (!cutX && !cutY) return 1.0;
    // Angle of the circle that lies outside W.
    double outside;
    if (cutX && cutY) {
        const double ax = std::acos(std::max(0.0, ex) / r), ay = std::acos(std::max(0.0, ey) / r);
        outside = ex * ex + ey * ey >= r * r ? 2.0 * (ax + ay) : ax + ay + 0.5 * kPi;
    } else {
        outside = 2.0 * std::acos(std::max(0.0, cutX ? ex : ey) / r);
    }
    return 2.0 * kPi / (2.0 * kPi - outside);
}

// ---------------------------------------------------------------------------------------
// CellWindow

std::vector<CellWindow> CellWindow::fromLabels(const Grid<std::int32_t>& labels, int nLabels, double maxLagM) {
    if (nLabels < 0) throw ValidationError("CellWindow: negative number of labels");
    if (!(maxLagM >= 0.0) || !std::isfinite(maxLagM))
        throw ValidationError("CellWindow: maximum lag must be finite and >= 0, got " + ppNum(maxLagM));
    const double cs = labels.cellSizeM();
    // One extra lag so that the bilinear interpolation is defined up to maxLagM; no more
    // lags than the grid has (beyond them every overlap is 0, which the lookup returns for
    // lags outside the table), so a huge maxLagM neither overflows nor allocates.
    const double lagCells = std::ceil(maxLagM / cs) + 1;
    const int lag = static_cast<int>(std::min(lagCells, static_cast<double>(std::max(labels.width(), labels.height()))));
    const int side = 2 * lag + 1;
    const std::size_t tableSize = static_cast<std::size_t>(side) * static_cast<std::size_t>(side);
    const std::size_t nl = static_cast<std::size_t>(nLabels);
    const int w = labels.width(), h = labels.height();
    std::vector<std::int64_t> total(nl * tableSize, 0);
    std::vector<std::int64_t> cellCount(nl, 0);

#pragma omp parallel
    {
        std::vector<std::int64_t> local(nl * tableSize, 0);
        std::vector<std::int64_t> localCells(nl, 0);
#pragma omp for schedule(dynamic, 4)
        for (int iy = 0; iy < h; ++iy) {
            const std::int32_t* row = labels.data().data() + static_cast<std::size_t>(iy) * static_cast<std::size_t>(w);
            for (int ix = 0; ix < w; ++ix) {
                const std::int32_t l = row[ix];
                if (l < 0 || l >= nLabels) continue;
                ++localCells[static_cast<std::size_t>(l)];
                std::int64_t* tab = local.data() + static_cast<std::size_t>(l) * tableSize;
                // Half of the lags (vy > 0, or vy == 0 and vx > 0); C(-v) = C(v) fills the rest.
                for (int vy = 0; vy <= lag && iy + vy < h; ++vy) {
                    const std::int32_t* row2 = row + static_cast<std::ptrdiff_t>(vy) * w;
                    const int vxLo = vy == 0 ? 1 : std::max(-lag, -ix);
                    const int vxHi = std::min(lag, w - 1 - ix);
                    std::int64_t* trow = tab + static_cast<std::size_t>(vy + lag) * static_cast<std::size_t>(side) + lag;
                    for (int vx = vxLo; vx <= vxHi; ++vx) trow[vx] += row2[ix + vx] == l;
                }
            }
        }
#pragma omp critical(eco_cellwindow_reduce)
        {
            for (std::size_t i = 0; i < local.size(); ++i) total[i] += local[i];
            for (std::size_t i = 0; i < nl; ++i) cellCount[i] += localCells[i];
        }
    }

    std::vector<CellWindow> out(nl);
    for (std::size_t l = 0; l < nl; ++l) {
        std::int64_t* t = total.data() + l * tableSize;
        auto at = [&](int vx, int vy) -> std::int64_t& { return t[static_cast<std::size_t>((vy + lag) * side + (vx + lag))]; };
        at(0, 0) = cellCount[l];
        for (int vy = 0; vy <= lag; ++vy)
            for (int vx = -lag; vx <= lag; ++vx)
                if (vy > 0 || vx > 0) at(-vx, -vy) = at(vx, vy);
        CellWindow& cw = out[l];
        cw.cellSizeM_ = cs;
        cw.invCell_ = 1.0 / cs;
        cw.lag_ = lag;
        cw.side_ = side;
        cw.areaM2_ = static_cast<double>(cellCount[l]) * cs * cs;
        cw.table_.resize(tableSize);
        for (std::size_t i = 0; i < tableSize; ++i) cw.table_[i] = static_cast<double>(t[i]) * cs * cs;
    }
    return out;
}

// ---------------------------------------------------------------------------------------
// PointGrid

PointGrid::PointGrid(const std::vector<double>& x, const std::vector<double>& y, double cellSizeM) {
    if (x.size() != y.size()) throw ValidationError("PointGrid: x and y differ in length");
    if (x.size() > 0xFFFFFFFFull) throw ValidationError("PointGrid: too many points");
    if (!(cellSizeM > 0.0) || !std::isfinite(cellSizeM))
        throw ValidationError("PointGrid: cell size must be positive, got " + ppNum(cellSizeM));
    const std::size_t n = x.size();
    if (n == 0) return;
    double minX = x[0], maxX = x[0], minY = y[0], maxY = y[0];
    for (std::size_t i = 0; i < n; ++i) {
        if (!std::isfinite(x[i]) || !std::isfinite(y[i]))
            throw ValidationError("PointGrid: point " + std::to_string(i) + " has a non-finite coordinate");
        minX = std::min(minX, x[i]);
        maxX = std::max(maxX, x[i]);
        minY = std::min(minY, y[i]);
        maxY = std::max(maxY, y[i]);
    }
    // Never more than about 4 cells per point (plus a floor): a tiny radius in a huge,
    // sparse pattern must not allocate a huge grid.
    const double maxCells = 4.0 * static_cast<double>(n) + 1024.0;
    double cell = cellSizeM;
    while (std::floor((maxX - minX) / cell + 1) * std::floor((maxY - minY) / cell + 1) > maxCells) cell *= 1.5;
    cell_ = cell;
    invCell_ = 1.0 / cell;
    ox_ = minX;
    oy_ = minY;
    nx_ = static_cast<int>(std::floor((maxX - minX) * invCell_)) + 1;
    ny_ = static_cast<int>(std::floor((maxY - minY) * invCell_)) + 1;
    const std::size_t ncell = static_cast<std::size_t>(nx_) * static_cast<std::size_t>(ny_);
    // Fresh pages of the large arrays faulted in by every thread (core/memory.h).
    std::vector<std::uint32_t> cellOf;
    resizeFresh(cellOf, n);
    assignFresh(start_, ncell + 1, std::size_t{0});
    for (std::size_t i = 0; i < n; ++i) {
        const int cx = std::min(nx_ - 1, static_cast<int>(std::floor((x[i] - ox_) * invCell_)));
        const int cy = std::min(ny_ - 1, static_cast<int>(std::floor((y[i] - oy_) * invCell_)));
        cellOf[i] = static_cast<std::uint32_t>(static_cast<std::size_t>(cy) * static_cast<std::size_t>(nx_) +
                                               static_cast<std::size_t>(cx));
        ++start_[cellOf[i] + 1];
    }
    for (std::size_t c = 0; c < ncell; ++c) start_[c + 1] += start_[c];
    std::vector<std::size_t> fill;
    resizeFresh(fill, ncell);
    std::copy(start_.begin(), start_.end() - 1, fill.begin());
    resizeFresh(order_, n);
    resizeFresh(xs_, n);
    resizeFresh(ys_, n);
    for (std::size_t i = 0; i < n; ++i) {  // stable counting sort: deterministic order
        const std::size_t s = fill[cellOf[i]]++;
        order_[s] = static_cast<std::uint32_t>(i);
        xs_[s] = x[i];
        ys_[s] = y[i];
    }
}

// ---------------------------------------------------------------------------------------
// Pair sums in a rectangle

PairSums PairSums::merged() const {
    PairSums m;
    m.nTypes = 1;
    m.bins = bins;
    m.window = window;
    m.typeCount.assign(1, 0);
    for (auto c : typeCount) m.typeCount[0] += c;
    const std::size_t nb = static_cast<std::size_t>(bins.count);
    m.pairCount.assign(nb, 0);
    m.translateSum.assign(nb, 0.0);
    if (!isotropicSum.empty()) m.isotropicSum.assign(nb, 0.0);
    for (int i = 0; i < nTypes; ++i)
        for (int j = 0; j < nTypes; ++j)
            for (int k = 0; k < bins.count; ++k) {
                const std::size_t a = index(i, j, k);
                m.pairCount[static_cast<std::size_t>(k)] += pairCount[a];
                m.translateSum[static_cast<std::size_t>(k)] += translateSum[a];
                if (!isotropicSum.empty()) m.isotropicSum[static_cast<std::size_t>(k)] += isotropicSum[a];
            }
    return m;
}

PairSums countPairs(const PointPattern& pattern, const RectWindow& window, const PcfOptions& options) {
    window.validate("pair correlation");
    options.bins.validate("pair correlation");
    const double halfShorter = 0.5 * std::min(window.widthM(), window.heightM());
    if (options.bins.rMaxM > halfShorter)
        throw ValidationError("pair correlation: rmax " + ppNum(options.bins.rMaxM) +
                              " m is beyond half the window's shorter side (" + ppNum(halfShorter) + " m)");
    const std::size_t n = pattern.size();
    if (pattern.y.size() != n || pattern.type.size() != n)
        throw ValidationError("pair correlation: x, y and type arrays differ in length");
    const int nTypes = static_cast<int>(pattern.typeNames.size());
    if (nTypes < 1) throw ValidationError("pair correlation: the pattern has no type names");

    PairSums out;
    out.nTypes = nTypes;
    out.bins = options.bins;
    out.window = window;
    out.typeCount.assign(static_cast<std::size_t>(nTypes), 0);
    for (std::size_t i = 0; i < n; ++i) {
        if (!window.contains(pattern.x[i], pattern.y[i]))
            throw ValidationError("pair correlation: point " + std::to_string(i) + " (" + ppNum(pattern.x[i]) + ", " +
                                  ppNum(pattern.y[i]) + ") lies outside the window");
        const int t = pattern.type[i];
        if (t < 0 || t >= nTypes)
            throw ValidationError("pair correlation: point " + std::to_string(i) + " has type " + std::to_string(t) +
                                  " outside 0.." + std::to_string(nTypes - 1));
        ++out.typeCount[static_cast<std::size_t>(t)];
    }
    const std::size_t histSize =
        static_cast<std::size_t>(nTypes) * static_cast<std::size_t>(nTypes) * static_cast<std::size_t>(options.bins.count);
    out.pairCount.assign(histSize, 0);
    out.translateSum.assign(histSize, 0.0);
    if (options.isotropic) out.isotropicSum.assign(histSize, 0.0);
    if (n < 2) return out;

    const double rMax = options.bins.rMaxM;
    const PointGrid grid(pattern.x, pattern.y, 0.5 * rMax);
    const std::vector<int> types = grid.permuted(pattern.type);
    const std::vector<double>& xs = grid.xs();
    const std::vector<double>& ys = grid.ys();
    std::vector<double> edgeDist(n);
    for (std::size_t s = 0; s < n; ++s) edgeDist[s] = window.distanceToEdgeM(xs[s], ys[s]);

    const int nb = options.bins.count;
    const double binsPerM = nb / rMax;
    const double areaW = window.areaM2(), wW = window.widthM(), hW = window.heightM();
    const bool iso = options.isotropic;
    const std::size_t nChunks = (n + kChunkPoints - 1) / kChunkPoints;
    const std::size_t batch = static_cast<std::size_t>(std::max(1, omp_get_max_threads())) * 8;

    struct Local {
        std::vector<std::int64_t> count;
        std::vector<double> trans, iso;
    };
    std::vector<Local> locals(std::min(batch, nChunks));
    for (auto& l : locals) {
        l.count.resize(histSize);
        l.trans.resize(histSize);
        if (iso) l.iso.resize(histSize);
    }
    for (std::size_t first = 0; first < nChunks; first += batch) {
        const std::size_t last = std::min(nChunks, first + batch);
#pragma omp parallel for schedule(dynamic, 1)
        for (std::size_t c = first; c < last; ++c) {
            Local& L = locals[c - first];
            std::fill(L.count.begin(), L.count.end(), 0);
            std::fill(L.trans.begin(), L.trans.end(), 0.0);
            if (iso) std::fill(L.iso.begin(), L.iso.end(), 0.0);
            const std::size_t sEnd = std::min(n, (c + 1) * kChunkPoints);
            for (std::size_t s = c * kChunkPoints; s < sEnd; ++s) {
                const double px = xs[s], py = ys[s];
                const std::size_t ti = static_cast<std::size_t>(types[s]);
                const double edgeS = edgeDist[s];
                // Each unordered pair once (t > s). Counts and translation weights (symmetric
                // in u) go to [ti][tj] only and are mirrored after the reduction; isotropic
                // weights differ by centre and go to both orders here.
                std::int64_t* countRow = L.count.data() + ti * static_cast<std::size_t>(nTypes) * static_cast<std::size_t>(nb);
                double* transRow = L.trans.data() + ti * static_cast<std::size_t>(nTypes) * static_cast<std::size_t>(nb);
                grid.forEachWithin(
                    px, py, rMax,
                    [&](std::size_t t, double dx, double dy, double d2) {
                        const double d = std::sqrt(d2);
                        int k = static_cast<int>(d * binsPerM);
                        if (k >= nb) k = nb - 1;
                        const std::size_t tj = static_cast<std::size_t>(types[t]);
                        const std::size_t a = tj * static_cast<std::size_t>(nb) + static_cast<std::size_t>(k);
                        ++countRow[a];
                        transRow[a] += areaW / ((wW - std::abs(dx)) * (hW - std::abs(dy)));
                        if (iso) {
                            L.iso[ti * static_cast<std::size_t>(nTypes) * static_cast<std::size_t>(nb) + a] +=
                                edgeS < d ? isotropicWeight(window, px, py, d) : 1.0;
                            L.iso[(tj * static_cast<std::size_t>(nTypes) + ti) * static_cast<std::size_t>(nb) +
                                  static_cast<std::size_t>(k)] +=
                                edgeDist[t] < d ? isotropicWeight(window, xs[t], ys[t], d) : 1.0;
                        }
                    },
                    s + 1);
            }
        }
        for (std::size_t c = first; c < last; ++c) {  // fixed order: deterministic sums
            const Local& L = locals[c - first];
            for (std::size_t i = 0; i < histSize; ++i) {
                out.pairCount[i] += L.count[i];
                out.translateSum[i] += L.trans[i];
            }
            if (iso)
                for (std::size_t i = 0; i < histSize; ++i) out.isotropicSum[i] += L.iso[i];
        }
    }
    // Mirror: ordered sums are H[i][j] + H[j][i] (twice H[i][i] on the diagonal).
    for (int i = 0; i < nTypes; ++i)
        for (int j = i; j < nTypes; ++j)
            for (int k = 0; k < nb; ++k) {
                const std::size_t a = out.index(i, j, k), b = out.index(j, i, k);
                const std::int64_t c = out.pairCount[a] + out.pairCount[b];
                const double w = out.translateSum[a] + out.translateSum[b];
                out.pairCount[a] = out.pairCount[b] = c;
                out.translateSum[a] = out.translateSum[b] = w;
            }
    return out;
}

// ---------------------------------------------------------------------------------------
// CSV

namespace {

bool splitCsv(const std::string& line, std::vector<std::string>& out) { return splitCsvLine(line, out); }

}  // namespace

PointPattern readPointPatternCsv(const std::string& path, const RectWindow* window) {
    std::ifstream in(path);
    if (!in) throw IoError(path + ": cannot open file (missing or unreadable)");
    noteInputFile(path);  // recorded in /provenance with its hash
    std::string line;
    std::vector<std::string> fields;
    int lineNo = 0;
    int cx = -1, cy = -1, cs = -1;
    std::size_t nFields = 0;
    while (std::getline(in, line)) {
        ++lineNo;
        if (trimmed(line).empty() || trimmed(line)[0] == '#') continue;
        if (!splitCsv(line, fields)) throw IoError(path + ":" + std::to_string(lineNo) + ": unterminated quote in the header");
        for (std::size_t i = 0; i < fields.size(); ++i) {
            std::string h = fields[i];
            std::transform(h.begin(), h.end(), h.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
            if ((h == "x" || h == "x_m") && cx < 0) cx = static_cast<int>(i);
            else if ((h == "y" || h == "y_m") && cy < 0) cy = static_cast<int>(i);
            else if ((h == "species" || h == "type") && cs < 0) cs = static_cast<int>(i);
        }
        nFields = fields.size();
        break;
    }
    if (cx < 0 || cy < 0)
        throw IoError(path + ":" + std::to_string(std::max(lineNo, 1)) +
                      ": the header must name the columns x and y (or x_m, y_m), optionally species");
    struct Row {
        double x, y;
        std::string type;
        int line;
    };
    std::vector<Row> rows;
    forEachCsvRow(in, path, lineNo, nFields, [&](const std::vector<std::string>& row, const std::string& where) {
        Row r{csvNumber(row, cx, "x", where), csvNumber(row, cy, "y", where),
              cs >= 0 ? row[static_cast<std::size_t>(cs)] : std::string("all"), lineNo};
        if (cs >= 0 && r.type.empty()) throw IoError(where + "column species is empty");
        if (window && !window->contains(r.x, r.y))
            throw IoError(where + "point (" + ppNum(r.x) + ", " + ppNum(r.y) + ") lies outside the window " + ppNum(window->x0) +
                          "," + ppNum(window->y0) + "," + ppNum(window->x1) + "," + ppNum(window->y1));
        rows.push_back(std::move(r));
    });
    PointPattern p;
    std::map<std::string, int> typeIndex;
    for (const Row& r : rows) typeIndex.emplace(r.type, 0);
    if (typeIndex.empty()) typeIndex.emplace("all", 0);
    for (auto& [name, index] : typeIndex) {
        index = static_cast<int>(p.typeNames.size());
        p.typeNames.push_back(name);
    }
    for (const Row& r : rows) {
        p.x.push_back(r.x);
        p.y.push_back(r.y);
        p.type.push_back(typeIndex[r.type]);
    }
    return p;
}

void writePcfCsv(const std::string& path, const PairSums& sums, const std::vector<std::string>& typeNames) {
    if (static_cast<int>(typeNames.size()) != sums.nTypes)
        throw ValidationError(path + ": " + std::to_string(typeNames.size()) + " type names for " +
                              std::to_string(sums.nTypes) + " types");
    AtomicOutput out(path);
    {
        std::FILE* f = std::fopen(out.tempPath().c_str(), "w");
        if (!f) throw IoError(path + ": cannot write CSV");
        // One header line, so that R's read.csv and pandas read it as it is (a leading comment
        // line broke them); the window is in every row's last columns.
        std::fprintf(f, "from,to,r_lo,r_hi,r_mid,pair_count,translate_weighted,normalisation_per_m2,g_trans,g_iso,"
                        "window_x0,window_y0,window_x1,window_y1\n");
        char windowText[128];
        std::snprintf(windowText, sizeof windowText, "%.10g,%.10g,%.10g,%.10g", sums.window.x0, sums.window.y0, sums.window.x1, sums.window.y1);
        auto block = [&](const PairSums& s, const std::vector<std::string>& names) {
            for (int i = 0; i < s.nTypes; ++i)
                for (int j = 0; j < s.nTypes; ++j)
                    for (int k = 0; k < s.bins.count; ++k) {
                        const std::size_t a = s.index(i, j, k);
                        std::fprintf(f, "%s,%s,%.10g,%.10g,%.10g,%lld,%.17g,%.17g,%.17g,", names[static_cast<std::size_t>(i)].c_str(),
                                     names[static_cast<std::size_t>(j)].c_str(), s.bins.loM(k), s.bins.hiM(k), s.bins.midM(k),
                                     static_cast<long long>(s.pairCount[a]), s.translateSum[a], s.normalisation(i, j),
                                     s.gTranslate(i, j, k));
                        if (!s.isotropicSum.empty()) std::fprintf(f, "%.17g", s.gIsotropic(i, j, k));
                        std::fprintf(f, ",%s\n", windowText);
                    }
        };
        block(sums, typeNames);
        if (sums.nTypes > 1 && std::find(typeNames.begin(), typeNames.end(), "all") == typeNames.end())
            block(sums.merged(), {"all"});
        if (std::fclose(f) != 0) throw IoError(path + ": error while writing CSV");
    }
    out.commit();
}

std::vector<double> nearestNeighbourDistances(const std::vector<double>& x, const std::vector<double>& y) {
    if (x.size() != y.size()) throw ValidationError("nearest neighbours: x and y differ in length");
    const std::size_t n = x.size();
    std::vector<double> out(n, std::numeric_limits<double>::infinity());
    if (n < 2) return out;
    // FLANN keeps a pointer to this row-major n x 2 matrix.
    std::vector<double> xy(2 * n);
    for (std::size_t i = 0; i < n; ++i) {
        xy[2 * i] = x[i];
        xy[2 * i + 1] = y[i];
    }
    const flann::Matrix<double> points(xy.data(), n, 2);
    flann::Index<flann::L2_Simple<double>> index(points, flann::KDTreeSingleIndexParams(10));
    index.buildIndex();
    // Two neighbours: the point itself and its nearest other (a coincident point can come
    // first instead of the point itself; either way the second distance is the answer).
    std::vector<std::size_t> ids(2 * n);
    std::vector<double> d2(2 * n);
    flann::Matrix<std::size_t> idm(ids.data(), n, 2);
    flann::Matrix<double> dm(d2.data(), n, 2);
    flann::SearchParams search(flann::FLANN_CHECKS_UNLIMITED);
    search.cores = 1;  // OpenMP parallelism below, over fixed chunks of queries
    constexpr std::size_t kChunk = 4096;
    const std::ptrdiff_t chunks = static_cast<std::ptrdiff_t>((n + kChunk - 1) / kChunk);
#pragma omp parallel for schedule(static)
    for (std::ptrdiff_t c = 0; c < chunks; ++c) {
        const std::size_t a = static_cast<std::size_t>(c) * kChunk, m = std::min(kChunk, n - a);
        flann::Matrix<double> q(xy.data() + 2 * a, m, 2);
        flann::Matrix<std::size_t> qi(ids.data() + 2 * a, m, 2);
        flann::Matrix<double> qd(d2.data() + 2 * a, m, 2);
        index.knnSearch(q, qi, qd, 2, search);
    }
    for (std::size_t i = 0; i < n; ++i) out[i] = std::sqrt(d2[2 * i + 1]);
    return out;
}

ClarkEvans clarkEvans(const std::vector<double>& x, const std::vector<double>& y, const RectWindow& window) {
    window.validate("Clark-Evans window");
    ClarkEvans r;
    r.n = x.size();
    if (r.n < 2) {
        r.meanNearestM = r.expectedM = r.index = std::numeric_limits<double>::quiet_NaN();
        return r;
    }
    const std::vector<double> d = nearestNeighbourDistances(x, y);
    double sum = 0;
    for (double v : d) sum += v;  // fixed order
    const double n = static_cast<double>(r.n);
    r.meanNearestM = sum / n;
    const double perimeter = 2.0 * (window.widthM() + window.heightM());
    r.expectedM = 0.5 * std::sqrt(window.areaM2() / n) + (0.0514 + 0.0412 / std::sqrt(n)) * perimeter / n;
    r.index = r.meanNearestM / r.expectedM;
    return r;
}

}  // namespace eco
