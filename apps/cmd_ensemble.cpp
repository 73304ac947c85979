// eco ensemble SPEC.toml: parsing, the processes that share the members (this one, child
// processes for members side by side, or the ranks of an MPI job), signals and progress. The
// members themselves, their status, the manifest and the database are in pipeline/ensemble.
#include <fcntl.h>
#include <omp.h>
#include <signal.h>
#include <spawn.h>
#include <sys/file.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <vector>

#include "atomic_file.h"
#include "cli_common.h"
#include "ensemble.h"
#include "error.h"
#include "process_group.h"
#include "provenance.h"
#include "text_format.h"

extern char** environ;

namespace eco::cli {

namespace {

struct EnsembleArgs {
    std::string spec;
    std::string outDir;
    bool dryRun = false;
    std::string member;  // one member in this process (the ensemble's own child processes)
    std::string run;     // with --member: the run it belongs to
};

std::atomic<bool> gStopEnsemble{false};
extern "C" void onEnsembleStop(int) { gStopEnsemble = true; }

/// The command line's reporter, stopped by SIGINT or SIGTERM (Slurm's warning before its
/// time limit): the running members stop after their simulation year, with a checkpoint.
class EnsembleReporter : public CliReporter {
public:
    bool stopRequested() override { return gStopEnsemble.load(); }
};

void installStopHandlers() {
    struct sigaction sa {};
    sa.sa_handler = onEnsembleStop;
    sigemptyset(&sa.sa_mask);
    sigaction(SIGINT, &sa, nullptr);
    sigaction(SIGTERM, &sa, nullptr);
}

std::string makeRunToken() {
    const auto now = std::chrono::system_clock::now().time_since_epoch();
    const auto ns = static_cast<unsigned long long>(std::chrono::duration_cast<std::chrono::nanoseconds>(now).count());
    char buf[40];
    std::snprintf(buf, sizeof buf, "%llx-%d", ns, static_cast<int>(::getpid()));
    return buf;
}

/// Holds OUT/.ensemble.lock for the life of the process: two runs of one ensemble at a time
/// would run its members twice. A process may run the same ensemble again (eco calibrate
/// runs one per evaluation): a folder it already holds is not locked twice.
void lockOutDir(const std::string& outDir) {
    ensureDirectory(outDir);
    const std::string path = (std::filesystem::path(outDir) / ".ensemble.lock").string();
    static std::set<std::string> held;
    const std::string key = std::filesystem::weakly_canonical(path).string();
    if (held.count(key)) return;
    const int fd = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    if (fd < 0) throw IoError(path + ": cannot open the ensemble's lock: " + std::strerror(errno));
    if (::flock(fd, LOCK_EX | LOCK_NB) != 0)
        throw ValidationError(outDir + ": another eco ensemble is running in this folder (it holds " + path + ")");
    // Kept open (and locked) until the process ends.
    held.insert(key);
}

/// Members run in this process, one after the other, claimed from the shared queue.
void runInProcess(const pipeline::EnsembleSpec& spec, const std::string& run, ProcessGroup& group, const std::string& who,
                  pipeline::Reporter& reporter) {
    for (std::size_t i = 0; i < spec.members.size() && !reporter.stopRequested(); ++i) {
        if (pipeline::memberStatus(spec, i).state == "done") continue;
        if (!pipeline::claimMember(spec, i, run)) continue;
        info(who + "member " + spec.members[i].id + " started (" + pipeline::overridesText(spec.members[i]) + ")");
        const pipeline::MemberStatus s = pipeline::runMember(spec, i, run, reporter);
        info(who + "member " + s.id + " " + s.state + " in " + formatNumber(s.seconds, 3) + " s" +
             (s.plants >= 0 ? ", " + std::to_string(s.plants) + " plants" : "") + (s.error.empty() ? "" : ": " + s.error) +
             "; " + pipeline::progressLine(spec, pipeline::countMembers(spec, run), group.size()));
        if (group.rank() == 0) pipeline::writeManifest(spec);
    }
}

/// Members side by side in child processes (`eco ensemble SPEC --member ID --run RUN`), each
/// with its share of the threads; a child's output goes to its member's log.txt.
void runInChildren(const pipeline::EnsembleSpec& spec, const std::string& run, pipeline::Reporter& reporter) {
    const int atOnce = spec.membersAtOnce;
    const int threads = std::max(1, omp_get_max_threads() / atOnce);
    std::map<pid_t, std::size_t> running;
    std::size_t next = 0;
    const auto spawn = [&](std::size_t i) {
        std::vector<std::string> args = {"eco", "--threads", std::to_string(threads)};
        if (!provenanceRecorded()) args.push_back("--no-provenance");
        args.insert(args.end(), {"ensemble", spec.path, "--out-dir", spec.outDir, "--member", spec.members[i].id, "--run", run});
        std::vector<char*> argv;
        for (auto& a : args) argv.push_back(a.data());
        argv.push_back(nullptr);
        const std::string log = (std::filesystem::path(pipeline::memberDir(spec, i)) / "log.txt").string();
        posix_spawn_file_actions_t actions;
        posix_spawn_file_actions_init(&actions);
        posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, log.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
        posix_spawn_file_actions_adddup2(&actions, STDOUT_FILENO, STDERR_FILENO);
        posix_spawn_file_actions_addopen(&actions, STDIN_FILENO, "/dev/null", O_RDONLY, 0);
        pid_t pid = 0;
        const int rc = posix_spawn(&pid, "/proc/self/exe", &actions, nullptr, argv.data(), environ);
        posix_spawn_file_actions_destroy(&actions);
        if (rc != 0) throw IoError("ensemble: cannot start a process for member " + spec.members[i].id + ": " + std::strerror(rc));
        running[pid] = i;
        info("ensemble: member " + spec.members[i].id + " started in process " + std::to_string(pid) + " (" +
             pipeline::overridesText(spec.members[i]) + ")");
    };
    bool forwarded = false;
    while (true) {
        while (!reporter.stopRequested() && static_cast<int>(running.size()) < atOnce && next < spec.members.size()) {
            const std::size_t i = next++;
            if (pipeline::memberStatus(spec, i).state == "done") continue;
            if (pipeline::claimMember(spec, i, run)) spawn(i);
        }
        if (running.empty()) break;
        int status = 0;
        const pid_t pid = ::waitpid(-1, &status, 0);
        if (pid < 0) {
            if (errno != EINTR) throw IoError(std::string("ensemble: waitpid: ") + std::strerror(errno));
            if (reporter.stopRequested() && !forwarded) {  // the children stop after their year, as we do
                for (const auto& [child, i] : running) ::kill(child, SIGTERM);
                forwarded = true;
            }
            continue;
        }
        const auto it = running.find(pid);
        if (it == running.end()) continue;
        const std::size_t i = it->second;
        running.erase(it);
        pipeline::MemberStatus s = pipeline::memberStatus(spec, i);
        if (s.run != run || s.state == "pending") {  // died before recording its status
            const std::string why = WIFSIGNALED(status) ? "its process was killed by signal " + std::to_string(WTERMSIG(status))
                                                        : "its process exited with status " + std::to_string(WEXITSTATUS(status));
            pipeline::recordMemberFailure(spec, i, run, why + " (see its log.txt)");
            s = pipeline::memberStatus(spec, i);
        }
        info("ensemble: member " + s.id + " " + s.state + " in " + formatNumber(s.seconds, 3) + " s" +
             (s.plants >= 0 ? ", " + std::to_string(s.plants) + " plants" : "") + (s.error.empty() ? "" : ": " + s.error) + "; " +
             pipeline::progressLine(spec, pipeline::countMembers(spec, run), atOnce));
        pipeline::writeManifest(spec);
    }
}

/// --member: one member in this process, for the parent that started it.
void runOneMember(const EnsembleArgs& a) {
    if (a.run.empty()) usageError("--member", "needs --run (the ensemble starts its member processes itself)");
    ::prctl(PR_SET_PDEATHSIG, SIGTERM);  // the parent killed: stop after the year, as it would
    const pipeline::EnsembleSpec spec = pipeline::loadEnsembleSpec(a.spec, a.outDir);
    for (std::size_t i = 0; i < spec.members.size(); ++i)
        if (spec.members[i].id == a.member) {
            EnsembleReporter reporter;
            pipeline::runMember(spec, i, a.run, reporter);
            return;
        }
    throw ValidationError(a.spec + ": no member '" + a.member + "'");
}

void printMembers(const pipeline::EnsembleSpec& spec) {
    for (std::size_t i = 0; i < spec.members.size(); ++i) {
        const pipeline::MemberStatus s = pipeline::memberStatus(spec, i);
        printResult("%s\t%s\t%s\n", s.id.c_str(), s.state.c_str(), pipeline::overridesText(spec.members[i]).c_str());
    }
}

void runEnsemble(const EnsembleArgs& a) {
    if (!a.member.empty()) {
        installStopHandlers();
        return runOneMember(a);
    }
    if (!a.run.empty()) usageError("--run", "only with --member");
    runEnsembleFile(a.spec, a.outDir, a.dryRun);
}

}  // namespace

int runEnsembleFile(const std::string& specPath, const std::string& outDir, bool dryRun, bool printPaths) {
    installStopHandlers();
    EnsembleArgs a;
    a.spec = specPath;
    a.outDir = outDir;
    a.dryRun = dryRun;
    ProcessGroup& group = joinProcessGroup();
    const int rank = group.rank();
    // Ranks that share a machine share its cores, unless told otherwise.
    if (group.localSize() > 1 && !threadsFlagGiven() && !std::getenv("OMP_NUM_THREADS"))
        omp_set_num_threads(std::max(1, omp_get_num_procs() / group.localSize()));
    const std::string who = group.size() > 1 ? "ensemble [rank " + std::to_string(rank) + "]: " : "ensemble: ";

    // Rank 0 reads the specification, takes the folder's lock and names the run; the others
    // learn the run (or rank 0's error) from it.
    pipeline::EnsembleSpec spec;
    std::string start;
    if (rank == 0) {
        try {
            spec = pipeline::loadEnsembleSpec(a.spec, a.outDir);
            if (!a.dryRun) {
                lockOutDir(spec.outDir);
                start = makeRunToken();
                pipeline::removeStaleClaims(spec, start);
            }
        } catch (const Error& e) {
            start = std::string("!") + e.what();
        }
    }
    start = group.broadcast(start);
    if (!start.empty() && start[0] == '!') {
        if (rank == 0) throw ValidationError(start.substr(1));
        throw ExitStatus(1, who + "stopped: rank 0 could not start the run");
    }
    if (rank != 0) spec = pipeline::loadEnsembleSpec(a.spec, a.outDir);
    if (a.dryRun) {
        if (rank == 0) printMembers(spec);
        return rank;
    }
    const std::string& run = start;
    if (rank == 0) {
        const bool children = group.size() == 1 && spec.membersAtOnce > 1;
        info("ensemble: " + std::to_string(spec.members.size()) + " members in " + spec.outDir + " (configuration " +
             spec.baseSource + "); " +
             (group.size() > 1 ? std::to_string(group.size()) + " MPI ranks" : children ? std::to_string(spec.membersAtOnce) + " members at once" : "one member at a time") +
             ", " + std::to_string(children ? std::max(1, omp_get_max_threads() / spec.membersAtOnce) : omp_get_max_threads()) +
             " threads each; run " + run);
        info("ensemble: " + pipeline::progressLine(spec, pipeline::countMembers(spec, run), group.size()));
    }
    EnsembleReporter reporter;
    if (group.size() == 1 && spec.membersAtOnce > 1) runInChildren(spec, run, reporter);
    else runInProcess(spec, run, group, who, reporter);
    group.barrier();

    // Rank 0 writes the manifest and, when every member is done, the database; every rank
    // ends with its verdict.
    std::string verdict;
    if (rank == 0) {
        try {
            const std::string manifest = pipeline::writeManifest(spec);
            const pipeline::EnsembleCounts c = pipeline::countMembers(spec, run);
            info("ensemble: " + pipeline::progressLine(spec, c, group.size()) + "; manifest " + manifest);
            if (c.done < static_cast<int>(spec.members.size())) {
                verdict = std::to_string(spec.members.size() - static_cast<std::size_t>(c.done)) + " of " +
                          std::to_string(spec.members.size()) + " members not done (" + std::to_string(c.failed) + " failed, " +
                          std::to_string(c.stopped + c.pending) + " stopped or not started; see " + manifest + "); " +
                          (c.failed > 0 ? "fix what failed, then run" : "run") +
                          " the same command again: finished members are kept" + (spec.database ? ", and the database is built when all are done" : "");
            } else if (spec.database) {
                const std::string db = pipeline::buildEnsembleDatabase(spec, reporter);
                if (printPaths) printResult("%s\n%s\n", manifest.c_str(), db.c_str());
            } else {
                if (printPaths) printResult("%s\n", manifest.c_str());
            }
        } catch (const Error& e) {
            verdict = e.what();
        }
        std::fflush(stdout);
    }
    verdict = group.broadcast(verdict);
    if (!verdict.empty()) throw ExitStatus(1, rank == 0 ? "ensemble: " + verdict : who + "the run is not complete (rank 0 says why)");
    return rank;
}

void registerEnsembleCommand(CLI::App& app) {
    auto a = std::make_shared<EnsembleArgs>();
    CLI::App* sub = app.add_subcommand(
        "ensemble",
        "Run many simulations (members) from one specification: an eco run configuration with keys varied over "
        "lists ([vary]) or listed per member ([[member]]), each member in OUT/members/<id>/, a manifest "
        "(OUT/manifest.csv) and a biome database analysed from all of them (OUT/biome-db.h5). Restartable: the same "
        "command skips finished members and resumes the others from their checkpoints. Under MPI (mpirun -n N eco "
        "ensemble SPEC) the ranks share the members (docs/ensemble.md).");
    sub->add_option("spec", a->spec, "Ensemble specification (TOML)")->required()->check(CLI::ExistingFile);
    sub->add_option("--out-dir", a->outDir, "Override [ensemble] out_dir");
    sub->add_flag("--dry-run", a->dryRun, "List the members, their settings and states without running them");
    sub->add_option("--member", a->member, "Run only this member, in this process (used by the ensemble's own child "
                                           "processes; needs --run)");
    sub->add_option("--run", a->run, "With --member: the run it belongs to");
    sub->callback([a] { runEnsemble(*a); });
}

}  // namespace eco::cli
