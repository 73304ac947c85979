// Output sets and the cleanup after dead writers (core/atomic_file.h). The same with real
// SIGKILLs of the eco binary: kill_test.cpp.
#include <catch2/catch.hpp>
#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "atomic_file.h"
#include "error.h"
#include "test_util.h"

namespace {

namespace fs = std::filesystem;

std::string readText(const std::string& path) {
    std::ifstream in(path);
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
}

void writePlain(const std::string& path, const std::string& text) { std::ofstream(path) << text; }

/// The id of a process that has ended (forked, exited, reaped): no process of that id runs.
pid_t deadPid() {
    const pid_t child = ::fork();
    if (child == 0) ::_exit(0);
    int status = 0;
    ::waitpid(child, &status, 0);
    return child;
}

std::string hidden(const std::string& finalPath, const std::string& tag, pid_t pid) {
    const fs::path p(finalPath);
    return (p.parent_path() / ("." + p.filename().string() + tag + std::to_string(pid))).string();
}

}  // namespace

TEST_CASE("AtomicOutputSet: files appear together at commit, none without it", "[atomic]") {
    eco::test::TempDir dir("atomic_set");
    const std::string a = dir.file("a.txt");
    fs::create_directories(dir.path() / "side");
    const std::string b = dir.file("side/b.txt");
    writePlain(a, "old a");
    writePlain(b, "old b");
    {
        eco::AtomicOutputSet set;
        eco::writeTextFile(a, "new a");
        eco::writeTextFile(b, "new b");
        CHECK(readText(a) == "old a");  // nothing renamed before the set commits
        CHECK(readText(set.readablePath(a)) == "new a");
        CHECK(set.readablePath(dir.file("other")) == dir.file("other"));
        CHECK(set.finalPaths().size() == 2);
        set.commit();
    }
    CHECK(readText(a) == "new a");
    CHECK(readText(b) == "new b");
    {
        eco::AtomicOutputSet set;
        eco::writeTextFile(a, "lost a");
        eco::writeTextFile(b, "lost b");
    }  // an error before commit(): the previous files stay, the temporaries go
    CHECK(readText(a) == "new a");
    CHECK(readText(b) == "new b");
    for (const auto& e : fs::recursive_directory_iterator(dir.path()))
        CHECK(e.path().filename().string().rfind('.', 0) != 0);
    // Without a set, a commit renames at once (the set is closed after commit()).
    eco::writeTextFile(a, "alone");
    CHECK(readText(a) == "alone");
}

TEST_CASE("cleanUpAfterDeadWriters completes a dead writer's set from its journal and drops an incomplete one",
          "[atomic]") {
    eco::test::TempDir dir("atomic_journal");
    const std::string a = dir.file("scene.h5"), b = dir.file("plants.csv");
    writePlain(a, "new scene");  // renamed before the kill
    writePlain(b, "old csv");
    const pid_t dead = deadPid();
    writePlain(hidden(b, ".tmp", dead), "new csv");
    writePlain(hidden(a, ".set", dead), "eco-output-set 1\n" + fs::absolute(hidden(a, ".tmp", dead)).string() + "\t" +
                                             fs::absolute(a).string() + "\n" + fs::absolute(hidden(b, ".tmp", dead)).string() +
                                             "\t" + fs::absolute(b).string() + "\nend\n");
    eco::cleanUpAfterDeadWriters(b);  // the side file's cleanup does not know the set: its temporary goes
    CHECK(fs::exists(hidden(a, ".set", dead)));
    writePlain(hidden(b, ".tmp", dead), "new csv");
    eco::cleanUpAfterDeadWriters(a);  // the first file's: the set is completed
    CHECK(readText(b) == "new csv");
    CHECK(readText(a) == "new scene");
    CHECK_FALSE(fs::exists(hidden(a, ".set", dead)));
    CHECK_FALSE(fs::exists(hidden(b, ".tmp", dead)));

    // A journal cut short (no `end`): nothing is renamed; journal and temporaries go.
    writePlain(hidden(b, ".tmp", dead), "newer csv");
    writePlain(hidden(a, ".set", dead), "eco-output-set 1\n" + fs::absolute(hidden(b, ".tmp", dead)).string() + "\t" +
                                             fs::absolute(b).string() + "\n");
    eco::cleanUpAfterDeadWriters(a);
    eco::cleanUpDirectoryAfterDeadWriters(dir.path().string());
    CHECK(readText(b) == "new csv");
    CHECK_FALSE(fs::exists(hidden(a, ".set", dead)));
    CHECK_FALSE(fs::exists(hidden(b, ".tmp", dead)));

    // A running writer's journal and temporaries are left alone.
    const pid_t running = ::getppid();
    writePlain(hidden(a, ".set", running), "eco-output-set 1\nend\n");
    writePlain(hidden(b, ".tmp", running), "partial");
    eco::cleanUpDirectoryAfterDeadWriters(dir.path().string());
    CHECK(fs::exists(hidden(a, ".set", running)));
    CHECK(fs::exists(hidden(b, ".tmp", running)));
}

TEST_CASE("cleanUpDirectoryAfterDeadWriters removes a dead image writer's temporary with its extension", "[atomic]") {
    // The PNG and EXR writers write `.<name>.tmp<pid>.png` (their library picks the format
    // from the extension) and rename it to `.<name>.tmp<pid>` before the commit: a kill in
    // between leaves the first name, which the cleanup must know.
    eco::test::TempDir dir("atomic_image");
    const std::string png = dir.file("plants_year_0008.png"), exr = dir.file("height.exr");
    const pid_t dead = deadPid(), running = ::getppid();
    writePlain(hidden(png, ".tmp", dead) + ".png", "half a png");
    writePlain(hidden(exr, ".tmp", dead) + ".exr", "half an exr");
    writePlain(hidden(png, ".tmp", running) + ".png", "a png being written");
    writePlain(dir.file(".notes.tmp12x.png"), "not a temporary");  // kept: not a pid
    writePlain(dir.file(".photo.tmp" + std::to_string(dead) + ".PNG!"), "not a temporary");
    eco::cleanUpDirectoryAfterDeadWriters(dir.path().string());
    CHECK_FALSE(fs::exists(hidden(png, ".tmp", dead) + ".png"));
    CHECK_FALSE(fs::exists(hidden(exr, ".tmp", dead) + ".exr"));
    CHECK(fs::exists(hidden(png, ".tmp", running) + ".png"));
    CHECK(fs::exists(dir.file(".notes.tmp12x.png")));
    CHECK(fs::exists(dir.file(".photo.tmp" + std::to_string(dead) + ".PNG!")));
    // The cleanup of one output takes its own image temporary only.
    writePlain(hidden(png, ".tmp", dead) + ".png", "half a png");
    writePlain(hidden(exr, ".tmp", dead) + ".exr", "half an exr");
    eco::cleanUpAfterDeadWriters(exr);
    CHECK(fs::exists(hidden(png, ".tmp", dead) + ".png"));
    CHECK_FALSE(fs::exists(hidden(exr, ".tmp", dead) + ".exr"));
}
