#include "ensemble.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

#include "atomic_file.h"
#include "biome.h"
#include "eco_version.h"
#include "error.h"
#include "run.h"
#include "sim_config.h"
#include "sim_file.h"
#include "stage_runner.h"
#include "strict_toml.h"
#include "text_format.h"

namespace eco::pipeline {

namespace fs = std::filesystem;

namespace {

/// FNV-1a, 64 bits, in hex: a stable fingerprint of configuration text (std::hash is not
/// the same across builds).
std::string fingerprint(const std::string& text) {
    std::uint64_t h = 1469598103934665603ull;
    for (unsigned char c : text) {
        h ^= c;
        h *= 1099511628211ull;
    }
    char buf[17];
    std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(h));
    return buf;
}

/// Writes `text` to `path` (atomically) unless the file already holds it: processes of a run
/// write a member's configuration files again when they check its status.
void writeIfChanged(const std::string& path, const std::string& text) {
    if (!fs::exists(path) || readTextFile(path) != text) writeTextFile(path, text);
}

std::string tomlText(const toml::table& t) {
    std::ostringstream s;
    s << t << "\n";
    return s.str();
}

/// A value as a person writes it: strings without quotes, numbers to 10 significant digits
/// (0.0003, not toml++'s 0.00029999999999999997), arrays in brackets.
std::string valueText(const toml::node& n) {
    if (const auto* str = n.as_string()) return str->get();
    if (const auto* f = n.as_floating_point()) return formatNumber(f->get(), 10);
    if (const auto* i = n.as_integer()) return std::to_string(i->get());
    if (const auto* b = n.as_boolean()) return b->get() ? "true" : "false";
    if (const auto* a = n.as_array()) {
        std::string s = "[";
        for (std::size_t k = 0; k < a->size(); ++k) s += (k ? ", " : "") + valueText(*a->get(k));
        return s + "]";
    }
    std::ostringstream s;
    n.visit([&](const auto& v) { s << v; });
    return s.str();
}

void setNode(toml::table& t, const std::string& key, const toml::node& value) {
    value.visit([&](const auto& v) { t.insert_or_assign(key, v); });
}

bool isIdentifier(const std::string& s) {
    return !s.empty() && s.size() <= 64 &&
           std::all_of(s.begin(), s.end(), [](char c) { return std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-'; });
}

/// The member's configuration files (member.toml, and simulate.toml and biome.toml when it
/// overrides model or biome keys), composed in memory: their paths in its folder, their
/// texts and the fingerprint of all of them with the code version.
struct MemberFiles {
    std::string config;  ///< member.toml's path
    std::string hash;
    std::vector<std::pair<std::string, std::string>> texts;  ///< path, content
};

MemberFiles composeMemberFiles(const EnsembleSpec& spec, std::size_t index) {
    const EnsembleMember& m = spec.members[index];
    // Absolute: member.toml lies in this folder, and a relative path in it would be read
    // relative to the folder (pipeline configurations resolve paths against their own directory).
    const std::string dir = fs::absolute(memberDir(spec, index)).lexically_normal().string();
    toml::table run = spec.base;
    toml::table sim, biome;
    bool simChanged = false, biomeChanged = false;
    for (const auto& [k, v] : m.overrides) {
        const std::string key(k.str());
        const auto parts = splitKey(key);
        const std::string where = spec.path + ": member '" + m.id + "': override '" + key + "'";
        if (parts.size() < 2) throw ValidationError(where + ": expected TABLE.KEY (e.g. terrain.seed)");
        if (parts[0] == "model" || parts[0] == "simulation") {
            if (!simChanged) {
                const auto* cfg = run["simulate"]["config"].as_string();
                if (!cfg) throw ValidationError(where + ": the base configuration's [simulate] has no config file to override");
                sim = sim::namesEmbeddedConfig(cfg->get()) ? toml::parse(sim::embeddedRunConfigToml(cfg->get()))
                                                            : parseTomlFile(cfg->get());
                // simulate.toml goes into the member's folder: its paths must not depend on where it was.
                absolutizeConfigPaths(sim, cfg->get(), sim::runConfigPathKeys());
                simChanged = true;
            }
            // model.KEY is short for simulation.model.KEY.
            setPath(sim, parts, parts[0] == "simulation" ? 1 : 0, v, where);
        } else if (parts[0] == "biome") {
            if (!biomeChanged) {
                const auto* file = run["run"]["biome"].as_string();
                biome = file && !file->get().empty() ? parseTomlFile(file->get()) : toml::parse(biomeToToml(defaultBiome()));
                biomeChanged = true;
            }
            setPath(biome, parts, 1, v, where);
        } else {
            setPath(run, parts, 0, v, where);
        }
    }
    // Paths an override sets are relative to the ensemble file, as its base table's are.
    absolutizeConfigPaths(run, spec.path, pipelineConfigPathKeys());
    const auto at = [&](const std::string& name) { return (fs::path(dir) / name).string(); };
    MemberFiles files;
    // The files a member reads by path (its simulation configuration, its biome) count too.
    std::string inputs;
    if (simChanged) {
        files.texts.emplace_back(at("simulate.toml"), tomlText(sim));
        setPath(run, {"simulate", "config"}, 0, toml::value<std::string>(at("simulate.toml")), spec.path);
        inputs += files.texts.back().second;
    } else if (const auto* cfg = run["simulate"]["config"].as_string()) {
        inputs += readTextFile(cfg->get());
    }
    if (biomeChanged) {
        files.texts.emplace_back(at("biome.toml"), tomlText(biome));
        setPath(run, {"run", "biome"}, 0, toml::value<std::string>(at("biome.toml")), spec.path);
        inputs += files.texts.back().second;
    } else if (const auto* b = run["run"]["biome"].as_string()) {
        inputs += readTextFile(b->get());
    }
    setPath(run, {"run", "out_dir"}, 0, toml::value<std::string>(dir), spec.path);
    const std::string runText = "# ensemble " + spec.path + ", member " + m.id + " (written by eco ensemble)\n" + tomlText(run);
    files.config = at("member.toml");
    files.texts.emplace_back(files.config, runText);
    files.hash = fingerprint(runText + inputs + ECO_VERSION_STRING);
    return files;
}

/// composeMemberFiles, written into the member's folder (files whose content is unchanged
/// are left alone).
MemberFiles writeMemberFiles(const EnsembleSpec& spec, std::size_t index) {
    MemberFiles files = composeMemberFiles(spec, index);
    ensureDirectory(memberDir(spec, index));
    for (const auto& [path, text] : files.texts) writeIfChanged(path, text);
    return files;
}

}  // namespace

std::vector<std::string> splitKey(const std::string& key) {
    std::vector<std::string> parts;
    std::stringstream ss(key);
    std::string part;
    while (std::getline(ss, part, '.')) parts.push_back(part);
    return parts;
}

/// Sets the dotted path `parts[from..]` of `root` to `value`: missing tables are created; in
/// an array of tables (a biome's [[species]] and [[sub_biome]]) the next part names the
/// element by its `name`. `where` names the override in messages.
void setPath(toml::table& root, const std::vector<std::string>& parts, std::size_t from, const toml::node& value,
             const std::string& where) {
    toml::table* t = &root;
    for (std::size_t i = from; i + 1 < parts.size(); ++i) {
        toml::node* n = t->get(parts[i]);
        if (!n) {
            t->insert_or_assign(parts[i], toml::table{});
            n = t->get(parts[i]);
        }
        if (toml::table* sub = n->as_table()) {
            t = sub;
            continue;
        }
        toml::array* a = n->as_array();
        if (!a || i + 2 >= parts.size())
            throw ValidationError(where + ": '" + parts[i] + "' is not a table");
        toml::table* found = nullptr;
        for (auto& e : *a)
            if (toml::table* et = e.as_table())
                if (const auto name = (*et)["name"].value<std::string>(); name && *name == parts[i + 1]) found = et;
        if (!found) throw ValidationError(where + ": no element named '" + parts[i + 1] + "' in '" + parts[i] + "'");
        t = found;
        ++i;
    }
    setNode(*t, parts.back(), value);
}


std::string writeMemberConfig(const EnsembleSpec& spec, std::size_t index) { return writeMemberFiles(spec, index).config; }

namespace {

std::string statusPath(const EnsembleSpec& spec, std::size_t index) { return (fs::path(memberDir(spec, index)) / "status.toml").string(); }

void writeStatus(const EnsembleSpec& spec, std::size_t index, const MemberStatus& s) {
    toml::table t;
    t.insert("member", s.id);
    t.insert("state", s.state);
    t.insert("config_hash", s.configHash);
    t.insert("run", s.run);
    t.insert("seconds", s.seconds);
    t.insert("plants", static_cast<std::int64_t>(s.plants));
    t.insert("years", static_cast<std::int64_t>(s.years));
    t.insert("error", s.error);
    writeTextFile(statusPath(spec, index), tomlText(t));
}

/// The recorded status as written (any configuration), "pending" when absent or unreadable.
MemberStatus recordedStatus(const EnsembleSpec& spec, std::size_t index) {
    MemberStatus s;
    s.id = spec.members[index].id;
    const std::string path = statusPath(spec, index);
    if (!fs::exists(path)) return s;
    try {
        const toml::table t = toml::parse_file(path);
        s.state = t["state"].value_or(std::string("pending"));
        s.configHash = t["config_hash"].value_or(std::string());
        s.run = t["run"].value_or(std::string());
        s.seconds = t["seconds"].value_or(0.0);
        s.plants = t["plants"].value_or(std::int64_t{-1});
        s.years = static_cast<int>(t["years"].value_or(std::int64_t{0}));
        s.error = t["error"].value_or(std::string());
    } catch (const toml::parse_error&) {
        s.state = "pending";  // written atomically, so only a hand-edited file gets here
    }
    return s;
}

/// The member's stage output: every line into OUT/members/<id>/log.txt; a stop request of
/// the ensemble's reporter reaches the member's simulation.
class MemberLog : public Reporter {
public:
    MemberLog(const std::string& path, Reporter& parent) : file_(path, std::ios::app), parent_(parent) {}
    std::ostream& out() override { return file_; }
    void info(const std::string& line) override { file_ << line << "\n" << std::flush; }
    std::unique_ptr<ProgressBar> progress(const std::string& label, long total) override {
        return std::make_unique<Bar>(*this, label, total);
    }
    bool stopRequested() override { return parent_.stopRequested(); }

private:
    /// A line when the work is finished: no bars in a log file.
    class Bar : public ProgressBar {
    public:
        Bar(MemberLog& log, std::string label, long total)
            : log_(log), label_(std::move(label)), total_(total), start_(std::chrono::steady_clock::now()) {}
        void update(long) override {}
        void finish() override {
            log_.info(label_ + ": " + std::to_string(total_) + " done in " +
                      formatNumber(std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count(), 3) + " s");
        }

    private:
        MemberLog& log_;
        std::string label_;
        long total_;
        std::chrono::steady_clock::time_point start_;
    };
    std::ofstream file_;
    Reporter& parent_;
};

/// A stage of a member, as the member runs it: the simulation continues from its checkpoint.
/// Line breaks as spaces: one manifest row per line.
std::string oneLine(std::string s) {
    std::replace(s.begin(), s.end(), '\n', ' ');
    return s;
}

StageOptions asMemberStage(StageOptions options) {
    if (auto* o = std::get_if<SimulateOptions>(&options)) o->resume = true;
    return options;
}

}  // namespace

std::string overridesText(const EnsembleMember& member) {
    std::string s;
    for (const auto& [k, v] : member.overrides) s += (s.empty() ? "" : ", ") + std::string(k.str()) + " = " + valueText(v);
    return s.empty() ? "the base configuration" : s;
}

std::string memberDir(const EnsembleSpec& spec, std::size_t index) {
    return (fs::path(spec.outDir) / "members" / spec.members[index].id).string();
}

EnsembleSpec loadEnsembleSpec(const std::string& path, const std::string& outOverride) {
    const toml::table root = parseTomlFile(path);
    StrictTable top(root, path, "");
    EnsembleSpec spec;
    spec.path = path;
    {
        StrictTable e(top.table("ensemble"), path, "[ensemble]");
        spec.outDir = outOverride.empty() ? pathRelativeToConfig(path, e.string("out_dir")) : outOverride;
        if (!outOverride.empty() && e.has("out_dir")) e.string("out_dir");
        spec.membersAtOnce = static_cast<int>(e.integerOr("members_at_once", 1));
        if (spec.membersAtOnce < 1 || spec.membersAtOnce > 256) e.fail("members_at_once", "must be in 1 .. 256");
        spec.database = e.booleanOr("database", true);
        spec.databasePath = e.has("database_path") ? pathRelativeToConfig(path, e.string("database_path"))
                                                   : (fs::path(spec.outDir) / "biome-db.h5").string();
        const std::int64_t kmax = e.integerOr("kmax", 6);
        if (kmax < 1 || kmax > 64) e.fail("kmax", "value " + std::to_string(kmax) + " must be in 1 .. 64");
        spec.kMax = static_cast<int>(kmax);
        spec.seed = e.integerOr("seed", 1);
        if (spec.seed < 0) e.fail("seed", "must not be negative");
        // The members' configuration: a file, or the table [ensemble.base] itself.
        if (!e.has("base")) e.fail("base", "missing: an eco run configuration file, or a table [ensemble.base]");
        if (const toml::node& b = e.node("base"); const auto* file = b.as_string()) {
            // The base file's paths are relative to the base file; the member's copy lives elsewhere.
            spec.base = parseTomlFile(pathRelativeToConfig(path, file->get()));
            absolutizeConfigPaths(spec.base, pathRelativeToConfig(path, file->get()), pipelineConfigPathKeys());
            spec.baseSource = file->get();
        } else if (const toml::table* t = b.as_table()) {
            spec.base = *t;
            absolutizeConfigPaths(spec.base, path, pipelineConfigPathKeys());
            spec.baseSource = path + " [ensemble.base]";
        } else {
            e.fail("base", "expected a file name or a table");
        }
        e.finish();
    }
    if (spec.base.contains("synth"))
        throw ValidationError(spec.baseSource + ": [synth]: an ensemble member ends with its simulation (and its analysis); "
                              "synthesize from the ensemble's database with eco synth");
    if (!spec.base.contains("simulate"))
        throw ValidationError(spec.baseSource + ": [simulate]: missing; every ensemble member is a simulation");

    // Members: the product of [vary]'s lists (keys in alphabetical order, the last varying
    // fastest), then each [[member]].
    std::vector<std::pair<std::string, const toml::array*>> axes;
    if (const toml::table* vary = top.optionalTable("vary")) {
        StrictTable v(*vary, path, "[vary]");
        for (const auto& [k, node] : *vary) {
            const std::string key(k.str());
            const toml::array& a = v.array(key);
            if (a.empty()) v.fail(key, "expected at least one value");
            axes.emplace_back(key, &a);
        }
        v.finish();
    }
    std::size_t combinations = axes.empty() ? 0 : 1;
    for (const auto& [key, a] : axes) {
        combinations *= a->size();
        if (combinations > 100000) throw ValidationError(path + ": [vary]: more than 100000 combinations");
    }
    const toml::array* explicitMembers = nullptr;
    if (top.has("member")) {
        explicitMembers = &top.array("member");
        if (explicitMembers->size() > 100000) throw ValidationError(path + ": [[member]]: more than 100000 members");
    }
    const std::size_t total = combinations + (explicitMembers ? explicitMembers->size() : 0);
    top.finish();
    const int width = std::max(2, static_cast<int>(std::to_string(std::max<std::size_t>(total, 1)).size()));
    const auto numberedId = [&](std::size_t i) {
        const std::string n = std::to_string(i + 1);
        return "m" + std::string(static_cast<std::size_t>(width) - std::min<std::size_t>(n.size(), static_cast<std::size_t>(width)), '0') + n;
    };
    for (std::size_t c = 0; c < combinations; ++c) {
        EnsembleMember m;
        m.id = numberedId(spec.members.size());
        std::size_t rest = c;
        for (std::size_t k = axes.size(); k-- > 0;) {
            const toml::array& a = *axes[k].second;
            setNode(m.overrides, axes[k].first, *a.get(rest % a.size()));
            rest /= a.size();
        }
        spec.members.push_back(std::move(m));
    }
    if (explicitMembers)
        for (std::size_t i = 0; i < explicitMembers->size(); ++i) {
            const toml::table* t = explicitMembers->get(i)->as_table();
            const std::string ctx = "[[member]] " + std::to_string(i + 1);
            if (!t) throw ValidationError(path + ": " + ctx + ": expected a table");
            EnsembleMember m;
            m.id = numberedId(spec.members.size());
            for (const auto& [k, v] : *t) {
                const std::string key(k.str());
                if (key == "name") {
                    const auto* s = v.as_string();
                    if (!s || !isIdentifier(s->get()))
                        throw ValidationError(path + ": " + ctx + ": field 'name': expected letters, digits, '_' or '-' (a folder name)");
                    m.id = s->get();
                } else {
                    setNode(m.overrides, key, v);
                }
            }
            spec.members.push_back(std::move(m));
        }
    if (spec.members.empty()) spec.members.push_back({numberedId(0), {}});
    std::set<std::string> ids, keys;
    for (const auto& m : spec.members) {
        if (!ids.insert(m.id).second) throw ValidationError(path + ": two members are named '" + m.id + "'");
        for (const auto& [k, v] : m.overrides) keys.insert(std::string(k.str()));
    }
    spec.variedKeys.assign(keys.begin(), keys.end());

    // Every member's configuration checked as eco run checks its own, before anything runs
    // and before anything is written: in a scratch copy of the output folder (eco run's
    // checks read the files and create the output folders), removed afterwards, so that a
    // bad member or --dry-run leaves the output folder as it was. Messages name the real folder.
    const fs::path scratch = fs::temp_directory_path() / ("eco-ensemble-check-" + fingerprint(path + std::to_string(::getpid())));
    struct RemoveScratch {
        fs::path dir;
        ~RemoveScratch() {
            std::error_code ec;
            fs::remove_all(dir, ec);
        }
    } removeScratch{scratch};
    EnsembleSpec check = spec;
    check.outDir = (scratch / "out").string();
    const auto realNames = [&](std::string message) {
        for (std::size_t at = message.find(check.outDir); at != std::string::npos; at = message.find(check.outDir, at + spec.outDir.size()))
            message.replace(at, check.outDir.size(), spec.outDir);
        return message;
    };
    for (std::size_t i = 0; i < spec.members.size(); ++i) {
        try {
            planRun(writeMemberFiles(check, i).config);
        } catch (const Error& err) {
            throw ValidationError(path + ": member '" + spec.members[i].id + "': " + realNames(err.what()));
        }
    }
    return spec;
}

MemberStatus memberStatus(const EnsembleSpec& spec, std::size_t index) {
    MemberStatus s = recordedStatus(spec, index);
    if (s.state == "pending") return s;
    if (s.configHash != composeMemberFiles(spec, index).hash) {
        MemberStatus fresh;
        fresh.id = s.id;
        return fresh;
    }
    return s;
}

MemberStatus runMember(const EnsembleSpec& spec, std::size_t index, const std::string& run, Reporter& reporter) {
    const auto t0 = std::chrono::steady_clock::now();
    MemberStatus s;
    s.id = spec.members[index].id;
    s.run = run;
    const std::string dir = memberDir(spec, index);
    ensureDirectory(dir);
    // Outputs of another configuration of this member (the specification, a file it names or
    // the code changed) are removed: stage commands name the configuration files by path, so
    // their stamps would not see the change, and the checkpoint belongs to the old model.
    const fs::path hashFile = fs::path(dir) / "config.hash";
    MemberFiles files = writeMemberFiles(spec, index);
    if (fs::exists(hashFile) && readTextFile(hashFile.string()) != files.hash) {
        for (const auto& e : fs::directory_iterator(dir))
            if (e.path().filename().string().rfind(".claim-", 0) != 0) fs::remove_all(e.path());
        files = writeMemberFiles(spec, index);
    }
    writeIfChanged(hashFile.string(), files.hash);
    s.configHash = files.hash;
    MemberLog log((fs::path(dir) / "log.txt").string(), reporter);
    log.info("== member " + s.id + ", run " + run + ", eco " + ECO_VERSION_STRING);
    std::string simulation;
    try {
        const RunPlan plan = planRun(files.config);
        StageRunner stages("member " + s.id, log, [&] { return std::make_unique<MemberLog>((fs::path(dir) / "log.txt").string(), reporter); });
        for (const PlannedStage& stage : plan.stages) {
            const StageOptions options = asMemberStage(stage.options);
            stages.run(stage.name, mainOutput(options), options);
            if (const auto* o = std::get_if<SimulateOptions>(&options)) simulation = o->out;
        }
        const SimulationFileData data = readSimulationFile(simulation);
        s.plants = static_cast<long long>(data.undergrowth.size());
        s.years = data.year;
        s.state = "done";
    } catch (const Error& e) {
        s.state = reporter.stopRequested() ? "stopped" : "failed";
        s.error = e.what();
        log.info("member " + s.id + " " + s.state + ": " + s.error);
    }
    s.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    writeStatus(spec, index, s);
    return s;
}

void recordMemberFailure(const EnsembleSpec& spec, std::size_t index, const std::string& run, const std::string& why) {
    MemberStatus s;
    s.id = spec.members[index].id;
    s.run = run;
    s.state = "failed";
    s.error = why;
    s.configHash = composeMemberFiles(spec, index).hash;
    writeStatus(spec, index, s);
}

bool claimMember(const EnsembleSpec& spec, std::size_t index, const std::string& run) {
    const std::string dir = memberDir(spec, index);
    ensureDirectory(dir);
    const std::string claim = (fs::path(dir) / (".claim-" + run)).string();
    const int fd = ::open(claim.c_str(), O_WRONLY | O_CREAT | O_EXCL, 0644);
    if (fd < 0) {
        if (errno == EEXIST) return false;
        throw IoError(claim + ": cannot create the member's claim: " + std::strerror(errno));
    }
    ::close(fd);
    return true;
}

void removeStaleClaims(const EnsembleSpec& spec, const std::string& run) {
    for (std::size_t i = 0; i < spec.members.size(); ++i) {
        const fs::path dir = memberDir(spec, i);
        std::error_code ec;
        if (!fs::is_directory(dir, ec)) continue;
        for (const auto& e : fs::directory_iterator(dir, ec)) {
            const std::string name = e.path().filename().string();
            if (name.rfind(".claim-", 0) == 0 && name != ".claim-" + run) fs::remove(e.path(), ec);
        }
    }
}

EnsembleCounts countMembers(const EnsembleSpec& spec, const std::string& run) {
    EnsembleCounts c;
    for (std::size_t i = 0; i < spec.members.size(); ++i) {
        const MemberStatus s = recordedStatus(spec, i);
        const bool thisRun = s.run == run && s.state != "pending";
        if (thisRun) {
            ++c.finishedThisRun;
            c.secondsThisRun += s.seconds;
        }
        const bool claimed = fs::exists(fs::path(memberDir(spec, i)) / (".claim-" + run));
        if (claimed && !thisRun) ++c.running;
        else if (s.state == "done") ++c.done;
        else if (s.state == "failed") ++c.failed;
        else if (s.state == "stopped") ++c.stopped;
        else ++c.pending;
    }
    return c;
}

std::string progressLine(const EnsembleSpec& spec, const EnsembleCounts& c, int workers) {
    std::string line = std::to_string(c.done) + " of " + std::to_string(spec.members.size()) + " done";
    if (c.failed) line += ", " + std::to_string(c.failed) + " failed";
    if (c.stopped) line += ", " + std::to_string(c.stopped) + " stopped";
    line += ", " + std::to_string(c.running) + " running";
    if (c.finishedThisRun > 0 && c.pending + c.running > 0) {
        const double perMember = c.secondsThisRun / c.finishedThisRun;
        const double left = perMember * (c.pending + 0.5 * c.running) / std::max(1, workers);
        line += left >= 120 ? "; about " + formatNumber(left / 60, 2) + " min left" : "; about " + formatNumber(left, 2) + " s left";
    }
    return line;
}

std::string writeManifest(const EnsembleSpec& spec) {
    std::ostringstream csv;
    csv << "member,state,seconds,plants,years";
    for (const auto& k : spec.variedKeys) csv << "," << csvField(k);
    csv << ",error,folder\n";
    for (std::size_t i = 0; i < spec.members.size(); ++i) {
        const MemberStatus s = memberStatus(spec, i);
        csv << s.id << "," << s.state << "," << formatNumber(s.seconds, 4) << ",";
        if (s.plants >= 0) csv << s.plants;
        csv << "," << (s.years > 0 ? std::to_string(s.years) : std::string());
        for (const auto& k : spec.variedKeys) {
            csv << ",";
            if (const toml::node* v = spec.members[i].overrides.get(k)) csv << csvField(valueText(*v));
        }
        csv << "," << csvField(oneLine(s.error)) << "," << csvField(memberDir(spec, i)) << "\n";
    }
    const std::string path = (fs::path(spec.outDir) / "manifest.csv").string();
    writeTextFile(path, csv.str());
    return path;
}

std::string buildEnsembleDatabase(const EnsembleSpec& spec, Reporter& reporter) {
    AnalyseOptions analyse;
    for (std::size_t i = 0; i < spec.members.size(); ++i) {
        const MemberStatus s = memberStatus(spec, i);
        if (s.state != "done")
            throw ValidationError("ensemble database: member '" + s.id + "' is " + s.state +
                                  (s.error.empty() ? "" : " (" + s.error + ")") + "; rerun eco ensemble to finish it");
        const RunPlan plan = planRun(writeMemberFiles(spec, i).config);
        for (const PlannedStage& stage : plan.stages) {
            if (const auto* o = std::get_if<SimulateOptions>(&stage.options)) {
                analyse.simulations.push_back(o->out);
                analyse.abiotics.push_back(o->abiotics);
            }
        }
    }
    const auto at = [&](const std::string& name) { return (fs::path(spec.outDir) / name).string(); };
    analyse.out = spec.databasePath;
    // The analysis' command names the simulations by path: a member rerun with another
    // configuration leaves it the same, so the members' fingerprints decide too.
    std::string members;
    for (std::size_t i = 0; i < spec.members.size(); ++i) members += spec.members[i].id + " " + memberStatus(spec, i).configHash + "\n";
    const std::string membersStamp = analyse.out + ".members";
    if (!fs::exists(membersStamp) || readTextFile(membersStamp) != members) fs::remove(analyse.out + ".cmd");
    analyse.kMax = spec.kMax;
    analyse.seed = spec.seed;
    InspectOptions inspect;
    inspect.database = analyse.out;
    inspect.out = at("database.txt");
    inspect.pngDir = at("png/database");
    StageRunner stages("ensemble", reporter, [&] { return std::make_unique<MemberLog>(at("database-log.txt"), reporter); });
    stages.run("database of " + std::to_string(analyse.simulations.size()) + " simulations", analyse.out, analyse);
    stages.run("database summary", inspect.out, inspect);
    writeIfChanged(membersStamp, members);
    return analyse.out;
}

}  // namespace eco::pipeline
