// An eco process that a test starts, stops at a named point and kills (the kill tests of
// kill_test.cpp and ensemble_cli_test.cpp), and the bytes of an output folder to compare.
#pragma once

#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <map>
#include <string>
#include <thread>
#include <vector>

#include "h5_compare.h"
#include "test_util.h"

namespace eco::test {

/// An eco process started by the test; killed (SIGKILL, by its pid) and reaped at scope exit
/// if the test left it running or stopped.
class EcoChild {
public:
    /// Starts `eco args...` with its output in `logPath`; with `pauseAt` non-empty the child
    /// stops itself at that point (ECO_TEST_PAUSE_AT).
    EcoChild(const std::vector<std::string>& args, const std::string& pauseAt, const std::string& logPath) {
        pid_ = ::fork();
        if (pid_ == 0) {
            if (pauseAt.empty()) ::unsetenv("ECO_TEST_PAUSE_AT");
            else ::setenv("ECO_TEST_PAUSE_AT", pauseAt.c_str(), 1);
            const int fd = ::open(logPath.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
            if (fd >= 0) {
                ::dup2(fd, 1);
                ::dup2(fd, 2);
                ::close(fd);
            }
            std::vector<char*> argv{const_cast<char*>(ECO_BINARY)};
            for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
            argv.push_back(nullptr);
            ::execv(ECO_BINARY, argv.data());
            ::_exit(127);
        }
    }
    EcoChild(const EcoChild&) = delete;
    EcoChild& operator=(const EcoChild&) = delete;
    ~EcoChild() {
        if (pid_ > 0 && !reaped_) {
            ::kill(pid_, SIGKILL);
            int status = 0;
            ::waitpid(pid_, &status, 0);
        }
    }
    pid_t pid() const { return pid_; }

    /// Waits for the child to stop at its pause point and kills it there: true; false when it
    /// exited instead (the point was never reached).
    bool killAtPausePoint() {
        int status = 0;
        if (::waitpid(pid_, &status, WUNTRACED) != pid_) return false;
        if (!WIFSTOPPED(status)) {
            reaped_ = true;
            exitCode_ = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
            return false;
        }
        return killNow();
    }
    /// Kills the child `delay` after now unless it exits before: true when it was killed.
    bool killAfter(std::chrono::milliseconds delay) {
        const auto until = std::chrono::steady_clock::now() + delay;
        while (std::chrono::steady_clock::now() < until) {
            int status = 0;
            if (::waitpid(pid_, &status, WNOHANG) == pid_) {
                reaped_ = true;
                exitCode_ = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
                return false;
            }
            std::this_thread::sleep_for(std::chrono::milliseconds(2));
        }
        return killNow();
    }
    /// Waits for the child to end by itself: its exit code (-1: killed by a signal).
    int wait() {
        if (!reaped_) {
            int status = 0;
            ::waitpid(pid_, &status, 0);
            reaped_ = true;
            exitCode_ = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
        }
        return exitCode_;
    }
    int exitCode() const { return exitCode_; }

private:
    bool killNow() {
        ::kill(pid_, SIGKILL);
        int status = 0;
        ::waitpid(pid_, &status, 0);
        reaped_ = true;
        // The child may have exited by itself between the last poll and the signal (the
        // signal then reaches a zombie): its exit code, as if it had not been killed.
        exitCode_ = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
        return WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL;
    }
    pid_t pid_ = -1;
    bool reaped_ = false;
    int exitCode_ = -1;
};

/// The bytes of every regular, non-hidden file under `dir`, by path relative to it.
inline std::map<std::string, std::string> snapshotFiles(const std::filesystem::path& dir) {
    std::map<std::string, std::string> out;
    for (const auto& e : std::filesystem::recursive_directory_iterator(dir))
        if (e.is_regular_file() && e.path().filename().string().rfind('.', 0) != 0)
            out[std::filesystem::relative(e.path(), dir).string()] = fileBytes(e.path().string());
    return out;
}

}  // namespace eco::test
