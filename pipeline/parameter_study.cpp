#include "parameter_study.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <numeric>
#include <sstream>

#include "atomic_file.h"
#include "error.h"
#include "h5io.h"
#include "run.h"
#include "sim_file.h"
#include "strict_toml.h"
#include "text_format.h"

namespace eco::pipeline {

namespace fs = std::filesystem;

namespace {

int parseYear(const std::string& s, const std::string& where, const std::string& text) {
    if (s.empty() || s.size() > 6 || !std::all_of(s.begin(), s.end(), [](char c) { return c >= '0' && c <= '9'; }))
        throw ValidationError(where + ": output '" + text + "': '" + s + "' is not a year (a whole number)");
    return std::stoi(s);
}

double mean(const std::vector<double>& v) { return v.empty() ? 0.0 : std::accumulate(v.begin(), v.end(), 0.0) / static_cast<double>(v.size()); }

}  // namespace

double heightQuantile(std::vector<double> heights, double q) {
    if (heights.empty()) return 0;
    std::sort(heights.begin(), heights.end());
    const double pos = q * static_cast<double>(heights.size() - 1);
    const auto lo = static_cast<std::size_t>(std::floor(pos));
    const std::size_t hi = std::min(lo + 1, heights.size() - 1);
    return heights[lo] + (pos - static_cast<double>(lo)) * (heights[hi] - heights[lo]);
}

std::vector<double> pairCorrelation(const std::vector<double>& x, const std::vector<double>& y, const RectWindow& window, const DistanceBins& bins) {
    std::vector<double> g(static_cast<std::size_t>(bins.count), 0.0);
    if (x.size() < 2) return g;
    PointPattern pattern;
    pattern.x = x;
    pattern.y = y;
    pattern.type.assign(x.size(), 0);
    pattern.typeNames = {"all"};
    PcfOptions opt;
    opt.bins = bins;
    opt.isotropic = false;
    const PairSums sums = countPairs(pattern, window, opt);
    for (int k = 0; k < bins.count; ++k) g[static_cast<std::size_t>(k)] = sums.gTranslate(0, 0, k);
    return g;
}

double pairCorrelationDistance(const PairCorrelationReference& ref, const std::vector<double>& simulatedG) {
    double sq = 0;
    int n = 0;
    for (int k = 0; k < ref.bins.count; ++k) {
        if (ref.bins.loM(k) < ref.rMinM - 1e-12) continue;
        const double d = simulatedG.at(static_cast<std::size_t>(k)) - ref.observed.at(static_cast<std::size_t>(k));
        sq += d * d;
        ++n;
    }
    return n > 0 ? std::sqrt(sq / n) : 0.0;
}

PairCorrelationReference pairCorrelationReference(const std::string& stemMap, const RectWindow& window, const std::string& species,
                                                  double rMaxM, int bins, double rMinM, double minHeightM) {
    PairCorrelationReference ref;
    ref.stemMap = stemMap;
    ref.window = window;
    ref.bins = DistanceBins{rMaxM, bins};
    ref.rMinM = rMinM;
    ref.minHeightM = minHeightM;
    if (!(rMaxM > 0) || bins < 1 || bins > 1000) throw ValidationError(stemMap + ": the pair correlation needs r_max > 0 and 1 .. 1000 bins");
    if (!(rMinM >= 0 && rMinM < rMaxM)) throw ValidationError(stemMap + ": r_min must lie in [0, r_max)");
    const PointPattern all = readPointPatternCsv(stemMap, &window);
    int type = -1;
    if (!species.empty()) {
        const auto it = std::find(all.typeNames.begin(), all.typeNames.end(), species);
        if (it == all.typeNames.end() || (all.typeNames.size() == 1 && all.typeNames[0] == "all"))
            throw ValidationError(stemMap + ": no species '" + species + "' in the stem map (its column species)");
        type = static_cast<int>(it - all.typeNames.begin());
    }
    std::vector<double> x, y;
    for (std::size_t i = 0; i < all.size(); ++i)
        if (type < 0 || all.type[i] == type) {
            x.push_back(all.x[i]);
            y.push_back(all.y[i]);
        }
    ref.points = x.size();
    if (x.size() < 2)
        throw ValidationError(stemMap + ": " + std::to_string(x.size()) + " stem(s)" + (species.empty() ? "" : " of " + species) +
                              " in the window; the pair correlation needs at least 2");
    ref.observed = pairCorrelation(x, y, window, ref.bins);
    return ref;
}

StudyParameter makeStudyParameter(const std::string& key, double low, double high, const std::string& where, bool logScale, bool integer) {
    if (!std::isfinite(low) || !std::isfinite(high) || !(low < high))
        throw ValidationError(where + ": expected LOW < HIGH, got [" + formatNumber(low, 10) + ", " + formatNumber(high, 10) + "]");
    if (key == "run.seed") throw ValidationError(where + ": run.seed is the replicates' own key");
    if (key.find('.') == std::string::npos) throw ValidationError(where + ": expected TABLE.KEY (e.g. biome.species.Toyon.alpha)");
    if (logScale && !(low > 0)) throw ValidationError(where + ": a log scale needs LOW > 0, got " + formatNumber(low, 10));
    if (integer && (low != std::floor(low) || high != std::floor(high) || std::fabs(low) > 1e9 || std::fabs(high) > 1e9))
        throw ValidationError(where + ": an integer parameter needs whole numbers LOW and HIGH (at most 1e9), got [" + formatNumber(low, 10) + ", " +
                              formatNumber(high, 10) + "]");
    StudyParameter p;
    p.key = key;
    p.low = low;
    p.high = high;
    p.logScale = logScale;
    p.integer = integer;
    return p;
}

double StudyParameter::at(double unit) const {
    const double u = std::clamp(unit, 0.0, 1.0);
    if (!integer) return logScale ? std::exp(std::log(low) + u * (std::log(high) - std::log(low))) : low + u * (high - low);
    // Whole numbers: n covers [n, n + 1) of the continuous range low .. high + 1 (of its log
    // with a log scale), so that every value has its share; u = 1 is the highest.
    const double top = high + 1;
    const double v = logScale ? std::exp(std::log(low) + u * (std::log(top) - std::log(low))) : low + u * (top - low);
    return std::min(high, std::floor(v));
}

double StudyParameter::unitOf(double value) const {
    if (!integer) return logScale ? (std::log(value) - std::log(low)) / (std::log(high) - std::log(low)) : (value - low) / (high - low);
    const double top = high + 1;
    const double mid = std::round(value) + 0.5;
    return logScale ? (std::log(mid) - std::log(low)) / (std::log(top) - std::log(low)) : (mid - low) / (top - low);
}

std::string StudyParameter::describe() const {
    std::string s = formatNumber(low, 6) + " .. " + formatNumber(high, 6);
    if (logScale && integer) return s + " (log, integer)";
    if (logScale) return s + " (log)";
    if (integer) return s + " (integer)";
    return s;
}

StudyParameter parseStudyParameter(const std::string& key, const toml::node& value, const std::string& path, const std::string& table,
                                   double* start) {
    const std::string where = path + ": " + table + " '" + key + "'";
    const std::string form = std::string("expected [LOW, HIGH] or { low = LOW, high = HIGH, scale = \"linear\" | \"log\", integer = true | false") +
                             (start ? ", start = START }" : " }");
    const auto num = [&](const toml::node* n) {
        if (const auto* f = n->as_floating_point()) return f->get();
        if (const auto* i = n->as_integer()) return static_cast<double>(i->get());
        throw ValidationError(where + ": " + form);
    };
    if (start) *start = std::nan("");
    if (const auto* a = value.as_array()) {
        if (a->size() != 2) throw ValidationError(where + ": " + form);
        return makeStudyParameter(key, num(a->get(0)), num(a->get(1)), where);
    }
    const auto* t = value.as_table();
    if (!t) throw ValidationError(where + ": " + form);
    StrictTable p(*t, path, table + " '" + key + "'");
    const double low = p.number("low"), high = p.number("high");
    const std::string scale = p.stringOr("scale", "linear");
    if (scale != "linear" && scale != "log") p.fail("scale", "'" + scale + "' is not linear or log");
    const bool integer = p.booleanOr("integer", false);
    if (start) *start = p.numberOr("start", std::nan(""));
    p.finish();
    StudyParameter sp = makeStudyParameter(key, low, high, where, scale == "log", integer);
    if (start && std::isfinite(*start)) {
        if (!(*start >= low && *start <= high))
            throw ValidationError(where + ": start " + formatNumber(*start, 10) + " lies outside [" + formatNumber(low, 10) + ", " + formatNumber(high, 10) + "]");
        if (integer && *start != std::floor(*start)) throw ValidationError(where + ": start " + formatNumber(*start, 10) + " of an integer parameter is not a whole number");
    }
    return sp;
}

std::string SimulationOutput::units() const {
    switch (measure) {
        case Measure::Share: return "fraction of undergrowth plants";
        case Measure::Density: return "plants per m2";
        case Measure::MeanHeight: return "m";
        case Measure::Cover: return "crown area per m2";
        case Measure::CountCv: return "coefficient of variation";
        case Measure::HeightQuantile: return "m";
        case Measure::PairCorrelation: return "rms difference of g(r) from the stem map's";
        case Measure::CountRatio: return "ratio of plant counts";
    }
    return "";
}

SimulationOutput parseSimulationOutput(const std::string& text, const std::string& where) {
    SimulationOutput o;
    o.text = text;
    const auto at = text.find('@');
    if (at == std::string::npos)
        throw ValidationError(where + ": output '" + text + "': expected MEASURE[:SPECIES]@YEAR (e.g. share:Toyon@30, density@30) or cv@FIRST-LAST");
    std::string head = text.substr(0, at);
    const std::string when = text.substr(at + 1);
    const auto colon = head.find(':');
    if (colon != std::string::npos) {
        o.species = head.substr(colon + 1);
        head = head.substr(0, colon);
        if (o.species.empty()) throw ValidationError(where + ": output '" + text + "': empty species name after ':'");
    }
    if (head == "share") o.measure = SimulationOutput::Measure::Share;
    else if (head == "density") o.measure = SimulationOutput::Measure::Density;
    else if (head == "mean_height") o.measure = SimulationOutput::Measure::MeanHeight;
    else if (head == "cover") o.measure = SimulationOutput::Measure::Cover;
    else if (head == "cv") o.measure = SimulationOutput::Measure::CountCv;
    else if (head == "ratio") o.measure = SimulationOutput::Measure::CountRatio;
    else if (head.rfind("height_q", 0) == 0) {
        const std::string q = head.substr(8);
        if (q.empty() || q.size() > 2 || !std::all_of(q.begin(), q.end(), [](char c) { return c >= '0' && c <= '9'; }) || std::stoi(q) < 1)
            throw ValidationError(where + ": output '" + text + "': expected height_qNN with NN a percentage in 1 .. 99 (e.g. height_q90)");
        o.measure = SimulationOutput::Measure::HeightQuantile;
        o.quantile = std::stoi(q) / 100.0;
    } else if (head == "pcf") o.measure = SimulationOutput::Measure::PairCorrelation;
    else
        throw ValidationError(where + ": output '" + text + "': unknown measure '" + head +
                              "' (share, density, mean_height, cover, height_qNN, cv or ratio; pcf in eco calibrate)");
    if (o.measure == SimulationOutput::Measure::Share && o.species.empty())
        throw ValidationError(where + ": output '" + text + "': share needs a species (share:SPECIES@YEAR)");
    if (o.measure == SimulationOutput::Measure::Density && !o.species.empty())
        throw ValidationError(where + ": output '" + text + "': density is of all undergrowth (share:SPECIES gives a species' part)");
    if (o.measure == SimulationOutput::Measure::CountCv) {
        if (!o.species.empty()) throw ValidationError(where + ": output '" + text + "': cv is of the total plant count (no species)");
        const auto dash = when.find('-');
        if (dash == std::string::npos) throw ValidationError(where + ": output '" + text + "': cv needs a window of years, cv@FIRST-LAST");
        o.year = parseYear(when.substr(0, dash), where, text);
        o.yearEnd = parseYear(when.substr(dash + 1), where, text);
        if (o.yearEnd <= o.year) throw ValidationError(where + ": output '" + text + "': the window's last year must follow its first");
    } else if (o.measure == SimulationOutput::Measure::CountRatio) {
        if (o.species.empty()) throw ValidationError(where + ": output '" + text + "': ratio needs a species (ratio:SPECIES@YEAR/OTHER)");
        const auto slash = when.find('/');
        if (slash == std::string::npos) throw ValidationError(where + ": output '" + text + "': ratio needs two years, ratio:SPECIES@YEAR/OTHER");
        o.year = parseYear(when.substr(0, slash), where, text);
        o.yearEnd = parseYear(when.substr(slash + 1), where, text);
        if (o.year == o.yearEnd) throw ValidationError(where + ": output '" + text + "': the ratio's two years must differ");
    } else if (o.measure == SimulationOutput::Measure::Share && when.find('-') != std::string::npos) {
        const auto dash = when.find('-');
        o.year = parseYear(when.substr(0, dash), where, text);
        o.yearEnd = parseYear(when.substr(dash + 1), where, text);
        if (o.yearEnd <= o.year) throw ValidationError(where + ": output '" + text + "': the window's last year must follow its first");
    } else {
        o.year = o.yearEnd = parseYear(when, where, text);
    }
    return o;
}

double measureOutput(const std::string& simulationPath, const SimulationOutput& output) {
    const h5::File f = h5::File::openRead(simulationPath);
    if (!f.hasAttr("/", "format") || f.attrString("/", "format") != kSimulationFormat)
        throw IoError(simulationPath + ": not an eco-simulation file");
    const std::vector<std::string> names = f.readStrings("/species_names");
    const std::vector<YearRecord> series = readTimeseries(f, "/timeseries", names.size());
    const double area = (f.attrDouble("/", "x1") - f.attrDouble("/", "x0")) * (f.attrDouble("/", "y1") - f.attrDouble("/", "y0"));
    if (!(area > 0)) throw IoError(simulationPath + ": the simulated area (x0, y0, x1, y1) is empty");
    int species = -1;
    if (!output.species.empty()) {
        const auto it = std::find(names.begin(), names.end(), output.species);
        if (it == names.end()) throw ValidationError(simulationPath + ": output '" + output.text + "': no species '" + output.species + "' in the simulation's biome");
        species = static_cast<int>(it - names.begin());
    }
    using M = SimulationOutput::Measure;
    if (output.measure == M::HeightQuantile || output.measure == M::PairCorrelation) {
        const std::string group = snapshotGroup("/snapshots", output.year);
        if (!f.exists(group)) {
            std::string years;
            if (f.exists("/snapshots"))
                for (const std::string& c : f.list("/snapshots")) years += (years.empty() ? "" : ", ") + std::to_string(std::atoi(c.c_str() + 5));
            throw ValidationError(simulationPath + ": output '" + output.text + "': no snapshot of year " + std::to_string(output.year) +
                                  " (snapshots: " + (years.empty() ? std::string("none") : years) + "; add the year to [run] snapshot_years)");
        }
        const std::vector<double> height = f.readF64(group + "/height");
        const std::vector<std::int32_t> id = f.readI32(group + "/species_id");
        const bool pcf = output.measure == M::PairCorrelation;
        if (pcf && !output.pcf) throw ValidationError(simulationPath + ": output '" + output.text + "': a pair correlation needs a stem map (an eco calibrate target)");
        int wanted = -1;
        if (species >= 0) {
            const std::vector<std::string> snapNames = f.exists(group + "/species_names") ? f.readStrings(group + "/species_names") : names;
            const auto it = std::find(snapNames.begin(), snapNames.end(), output.species);
            if (it == snapNames.end()) throw ValidationError(simulationPath + ": output '" + output.text + "': no species '" + output.species + "' in the snapshot");
            wanted = static_cast<int>(it - snapNames.begin());
        }
        if (pcf) {
            const std::vector<double> x = f.readF64(group + "/x"), y = f.readF64(group + "/y");
            const RectWindow window{f.attrDouble("/", "x0"), f.attrDouble("/", "y0"), f.attrDouble("/", "x1"), f.attrDouble("/", "y1")};
            std::vector<double> px, py;
            for (std::size_t i = 0; i < height.size() && i < id.size() && i < x.size() && i < y.size(); ++i)
                if ((wanted < 0 || id[i] == wanted) && height[i] >= output.pcf->minHeightM && window.contains(x[i], y[i])) {
                    px.push_back(x[i]);
                    py.push_back(y[i]);
                }
            try {
                return pairCorrelationDistance(*output.pcf, pairCorrelation(px, py, window, output.pcf->bins));
            } catch (const ValidationError& e) {
                throw ValidationError(simulationPath + ": output '" + output.text + "': " + e.what());
            }
        }
        std::vector<double> h;
        for (std::size_t i = 0; i < height.size() && i < id.size(); ++i)
            if (wanted < 0 || id[i] == wanted) h.push_back(height[i]);
        return heightQuantile(h, output.quantile);
    }
    const auto record = [&](int year) -> const YearRecord& {
        for (const YearRecord& r : series)
            if (r.year == year) return r;
        throw ValidationError(simulationPath + ": output '" + output.text + "': year " + std::to_string(year) + " is not in its time series (years " +
                              (series.empty() ? std::string("none") : std::to_string(series.front().year) + " .. " + std::to_string(series.back().year)) + ")");
    };
    const auto total = [](const YearRecord& r) {
        double n = 0;
        for (auto c : r.count) n += c;
        return n;
    };
    if (output.measure == M::CountCv) {
        std::vector<double> counts;
        for (int y = output.year; y <= output.yearEnd; ++y) counts.push_back(total(record(y)));
        const double m = mean(counts);
        double sq = 0;
        for (double c : counts) sq += (c - m) * (c - m);
        return m > 0 ? std::sqrt(sq / static_cast<double>(counts.size())) / m : 0.0;
    }
    const auto s = static_cast<std::size_t>(species);
    if (output.measure == M::CountRatio) {
        const double below = record(output.yearEnd).count[s];
        return record(output.year).count[s] / std::max(1.0, below);
    }
    if (output.measure == M::Share && output.yearEnd > output.year) {
        std::vector<double> shares;
        for (int y = output.year; y <= output.yearEnd; ++y) {
            const YearRecord& w = record(y);
            const double n = total(w);
            shares.push_back(n > 0 ? w.count[s] / n : 0.0);
        }
        return mean(shares);
    }
    const YearRecord& r = record(output.year);
    switch (output.measure) {
        case M::Share: {
            const double n = total(r);
            return n > 0 ? r.count[s] / n : 0.0;
        }
        case M::Density: return total(r) / area;
        case M::MeanHeight: {
            if (species >= 0) return r.meanHeightM[s];
            double h = 0;
            for (std::size_t i = 0; i < r.count.size(); ++i) h += r.count[i] * r.meanHeightM[i];
            const double n = total(r);
            return n > 0 ? h / n : 0.0;
        }
        case M::Cover: {
            if (species >= 0) return r.crownAreaM2[s] / area;
            return std::accumulate(r.crownAreaM2.begin(), r.crownAreaM2.end(), 0.0) / area;
        }
        case M::CountCv:
        case M::CountRatio:
        case M::HeightQuantile:
        case M::PairCorrelation: break;
    }
    return 0;
}

std::string writeStudyEnsemble(const std::string& outDir, const toml::table& base, int membersAtOnce,
                               const std::vector<StudyParameter>& parameters, const std::vector<StudyMember>& members,
                               const std::string& comment) {
    toml::table ensemble;
    // Absolute: this file lies in outDir, and its paths are read relative to it.
    ensemble.insert("out_dir", (fs::absolute(outDir) / "ensemble").lexically_normal().string());
    ensemble.insert("database", false);
    ensemble.insert("members_at_once", static_cast<std::int64_t>(membersAtOnce));
    ensemble.insert("base", base);
    toml::array list;
    for (const StudyMember& member : members) {
        toml::table m;
        m.insert("name", member.name);
        for (std::size_t i = 0; i < parameters.size(); ++i) {
            if (parameters[i].integer) m.insert(parameters[i].key, static_cast<std::int64_t>(std::llround(member.values.at(i))));
            else m.insert(parameters[i].key, member.values.at(i));
        }
        m.insert("run.seed", static_cast<std::int64_t>(member.seed));
        list.push_back(std::move(m));
    }
    toml::table root;
    root.insert("ensemble", std::move(ensemble));
    root.insert("member", std::move(list));
    std::ostringstream text;
    text << comment << root << "\n";
    ensureDirectory(outDir);
    const std::string path = (fs::path(outDir) / "ensemble.toml").string();
    if (!fs::exists(path) || readTextFile(path) != text.str()) writeTextFile(path, text.str());
    return path;
}

std::string studySimulation(const std::string& outDir, const std::string& member) {
    return (fs::path(outDir) / "ensemble" / "members" / member / "simulation.h5").string();
}

toml::table studyBase(const toml::node& node, const std::string& specPath, const std::string& where) {
    // The base's paths are made absolute: the study runs it from an ensemble file in its out_dir.
    if (const auto* file = node.as_string()) {
        const std::string basePath = pathRelativeToConfig(specPath, file->get());
        toml::table t = parseTomlFile(basePath);
        absolutizeConfigPaths(t, basePath, pipelineConfigPathKeys());
        return t;
    }
    if (const auto* t = node.as_table()) {
        toml::table copy = *t;
        absolutizeConfigPaths(copy, specPath, pipelineConfigPathKeys());
        return copy;
    }
    throw ValidationError(where + ": expected an eco run configuration file name or a table");
}

}  // namespace eco::pipeline
