// eco ensemble SPEC.toml (issue 27): many members, each an eco run configuration (terrain,
// CHM, abiotics, canopy, simulation, optionally its own analysis) with some keys overridden,
// each in its own folder; a manifest of their settings, state and figures; and one biome
// database analysed from all of them. docs/ensemble.md describes the file and the layout.
//
// Runs are restartable: a member's stages are reused when their outputs and commands are
// unchanged (StageRunner), the simulation continues from its checkpoint, and a finished
// member is skipped. Members are handed out by claiming them (an exclusive file per member
// and run), so that several processes of one run (MPI ranks) share the work without a
// coordinator; every member is deterministic on its own, so the outputs are the same bytes
// whoever ran it and with how many threads.
#pragma once

#include <toml++/toml.h>

#include <cstdint>
#include <string>
#include <vector>

#include "reporter.h"
#include "run.h"

namespace eco::pipeline {

struct EnsembleMember {
    std::string id;         ///< its folder under OUT/members/
    /// Dotted keys: of the eco run configuration ("terrain.seed"), of its simulation
    /// configuration ("simulation.run.checkpoint_every_years"; "model.KEY" for its [model]) or
    /// of its biome ("biome.species.Toyon.alpha", species and sub-biomes by name).
    toml::table overrides;
};

struct EnsembleSpec {
    std::string path;    ///< the specification file
    std::string outDir;  ///< [ensemble] out_dir (or the override)
    toml::table base;    ///< the members' eco run configuration before the overrides
    std::string baseSource;
    int membersAtOnce = 1;  ///< members side by side in one process (child processes)
    bool database = true;   ///< analyse every member's simulation into databasePath
    std::string databasePath;  ///< [ensemble] database_path, default OUT/biome-db.h5
    int kMax = 6;
    std::int64_t seed = 1;  ///< the analysis' seed
    std::vector<EnsembleMember> members;
    std::vector<std::string> variedKeys;  ///< every overridden key, sorted (manifest columns)
};

/// Reads and checks a specification (ValidationError naming the file and key), and checks
/// every member's configuration as eco run would, so that a bad override stops the run
/// before anything is simulated; writes nothing into the output folder.
/// `outOverride` replaces [ensemble] out_dir when not empty.
EnsembleSpec loadEnsembleSpec(const std::string& path, const std::string& outOverride = "");

/// "a.b.c" -> {"a", "b", "c"}.
std::vector<std::string> splitKey(const std::string& key);
/// Sets the dotted path `parts[from..]` of `root` to `value`: missing tables are created; in
/// an array of tables (a biome's [[species]] and [[sub_biome]]) the next part names the
/// element by its `name`. `where` names the override in messages (ValidationError).
void setPath(toml::table& root, const std::vector<std::string>& parts, std::size_t from, const toml::node& value,
             const std::string& where);

/// "terrain.seed = 2, model.seeding_probability = 0.0003" (or "the base configuration").
std::string overridesText(const EnsembleMember& member);

/// OUT/members/<id>.
std::string memberDir(const EnsembleSpec& spec, std::size_t index);

/// Writes the member's configuration files into its folder (member.toml; simulate.toml and
/// biome.toml when it overrides model or biome keys) and returns member.toml's path.
/// loadEnsembleSpec writes nothing; runMember calls this.
std::string writeMemberConfig(const EnsembleSpec& spec, std::size_t index);

struct MemberStatus {
    std::string id;
    std::string state = "pending";  ///< pending, done, failed, stopped
    std::string configHash;         ///< of the member's configuration files and the code version
    std::string run;                ///< the run (its token) that wrote this status
    double seconds = 0;             ///< wall time of that run of the member
    long long plants = -1;          ///< undergrowth plants at the end of the simulation
    int years = 0;
    std::string error;
};

/// The member's recorded status; "pending" when there is none or it was written for another
/// configuration (the specification or the code changed since).
MemberStatus memberStatus(const EnsembleSpec& spec, std::size_t index);

/// Runs one member in this process: writes its configuration files, runs (or reuses) its
/// stages with their output in OUT/members/<id>/log.txt, and records its status (done,
/// failed with the error, or stopped when reporter.stopRequested()). Never throws for the
/// member's own errors; `run` is the token of the current run.
MemberStatus runMember(const EnsembleSpec& spec, std::size_t index, const std::string& run, Reporter& reporter);

/// Records a member as failed without running it (its process died: `why`).
void recordMemberFailure(const EnsembleSpec& spec, std::size_t index, const std::string& run, const std::string& why);

/// Claims a member for this process in run `run` (an exclusive file in its folder): true
/// for exactly one claimant per member and run.
bool claimMember(const EnsembleSpec& spec, std::size_t index, const std::string& run);

/// Removes the claims of other runs (at the start of a run, by one process).
void removeStaleClaims(const EnsembleSpec& spec, const std::string& run);

struct EnsembleCounts {
    int done = 0, failed = 0, stopped = 0, running = 0, pending = 0;
    double secondsThisRun = 0;  ///< sum over the members finished in this run
    int finishedThisRun = 0;
};
/// The state of the whole ensemble from the members' files (any process can call it).
EnsembleCounts countMembers(const EnsembleSpec& spec, const std::string& run);
/// "5 of 12 done, 1 failed, 2 running; about 3.2 min left" (`workers` processes at work).
std::string progressLine(const EnsembleSpec& spec, const EnsembleCounts& counts, int workers);

/// OUT/manifest.csv: one row per member (id, state, seconds, plants, years, every varied
/// key, error, folder), written atomically. Returns its path.
std::string writeManifest(const EnsembleSpec& spec);

/// Analyses every member's simulation into spec.databasePath (its summary in
/// OUT/database.txt, its pictures in OUT/png/database), reused
/// when up to date. ValidationError when a member is not done. Returns the database path.
std::string buildEnsembleDatabase(const EnsembleSpec& spec, Reporter& reporter);

}  // namespace eco::pipeline
