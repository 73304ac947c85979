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

StudyParameter makeStudyParameter(const std::string& key, double low, double high, const std::string& where) {
    if (!std::isfinite(low) || !std::isfinite(high) || !(low < high))
        throw ValidationError(where + ": expected LOW < HIGH, got [" + formatNumber(low, 10) + ", " + formatNumber(high, 10) + "]");
    if (key == "run.seed") throw ValidationError(where + ": run.seed is the replicates' own key");
    if (key.find('.') == std::string::npos) throw ValidationError(where + ": expected TABLE.KEY (e.g. biome.species.Toyon.alpha)");
    return {key, low, high};
}

std::string SimulationOutput::units() const {
    switch (measure) {
        case Measure::Share: return "fraction of undergrowth plants";
        case Measure::Density: return "plants per m2";
        case Measure::MeanHeight: return "m";
        case Measure::Cover: return "crown area per m2";
        case Measure::CountCv: return "coefficient of variation";
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
    else
        throw ValidationError(where + ": output '" + text + "': unknown measure '" + head +
                              "' (share, density, mean_height, cover or cv)");
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
    using M = SimulationOutput::Measure;
    if (output.measure == M::CountCv) {
        std::vector<double> counts;
        for (int y = output.year; y <= output.yearEnd; ++y) counts.push_back(total(record(y)));
        const double m = mean(counts);
        double sq = 0;
        for (double c : counts) sq += (c - m) * (c - m);
        return m > 0 ? std::sqrt(sq / static_cast<double>(counts.size())) / m : 0.0;
    }
    const YearRecord& r = record(output.year);
    const auto s = static_cast<std::size_t>(species);
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
        case M::CountCv: break;
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
        for (std::size_t i = 0; i < parameters.size(); ++i) m.insert(parameters[i].key, member.values.at(i));
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
