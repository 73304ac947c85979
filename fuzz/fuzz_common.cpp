#include "fuzz_common.h"

#include <fcntl.h>
#include <hdf5.h>
#include <omp.h>
#include <sanitizer/common_interface_defs.h>
#include <signal.h>
#include <sys/mman.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <vector>

namespace eco::fuzz {

namespace {

std::string makeScratchDir() {
    std::string base = "/dev/shm";
    if (!std::filesystem::is_directory(base) || ::access(base.c_str(), W_OK) != 0) {
        const char* tmp = std::getenv("TMPDIR");
        base = tmp && *tmp ? tmp : "/tmp";
    }
    std::string pattern = base + "/eco-fuzz-XXXXXX";
    if (!::mkdtemp(pattern.data())) {
        std::perror("eco fuzz: mkdtemp");
        std::abort();
    }
    return pattern;
}

void removeScratchDir() {
    std::error_code ec;
    std::filesystem::remove_all(scratchDir(), ec);
}

}  // namespace

const std::string& scratchDir() {
    static const std::string dir = makeScratchDir();
    return dir;
}

void initialize(int* argc, char*** argv) {
    long rssLimitMb = 2048;  // libFuzzer's default -rss_limit_mb
    for (int i = 1; i < *argc; ++i) {
        const char* a = (*argv)[i];
        static const char kFlag[] = "-rss_limit_mb=";
        if (std::strncmp(a, kFlag, sizeof kFlag - 1) == 0) rssLimitMb = std::atol(a + sizeof kFlag - 1);
    }
    if (rssLimitMb > 0) {
        const std::string budget = std::to_string(rssLimitMb / 2);
        ::setenv("ECO_MEMORY_LIMIT_MB", budget.c_str(), 1);
    }
    omp_set_num_threads(1);
    scratchDir();
    std::atexit(removeScratchDir);
}

std::string writeInput(const std::uint8_t* data, std::size_t size, const std::string& name) {
    const std::string path = scratchDir() + "/" + name;
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
    out.close();
    if (!out) {
        std::fprintf(stderr, "eco fuzz: cannot write %s\n", path.c_str());
        std::abort();
    }
    return path;
}

}  // namespace eco::fuzz

namespace eco::fuzz {

namespace {

constexpr double kWalkMaxBytes = 64.0 * 1024 * 1024;

/// Read a dataset's or attribute's whole content in its native memory type.
template <class ReadFn>
void readAll(hid_t fileType, hid_t space, ReadFn&& read) {
    const hssize_t n = H5Sget_simple_extent_npoints(space);
    const hid_t memType = H5Tget_native_type(fileType, H5T_DIR_DEFAULT);
    if (memType < 0) return;
    const std::size_t size = H5Tget_size(memType);
    if (n > 0 && size > 0 && static_cast<double>(n) * static_cast<double>(size) <= kWalkMaxBytes) {
        std::vector<unsigned char> buf(static_cast<std::size_t>(n) * size);
        if (read(memType, buf.data()) >= 0) H5Dvlen_reclaim(memType, space, H5P_DEFAULT, buf.data());
    }
    H5Tclose(memType);
}

herr_t walkAttribute(hid_t object, const char* name, const H5A_info_t*, void*) {
    const hid_t a = H5Aopen(object, name, H5P_DEFAULT);
    if (a < 0) return 0;
    const hid_t type = H5Aget_type(a), space = H5Aget_space(a);
    if (type >= 0 && space >= 0) readAll(type, space, [&](hid_t mem, void* buf) { return H5Aread(a, mem, buf); });
    if (type >= 0) H5Tclose(type);
    if (space >= 0) H5Sclose(space);
    H5Aclose(a);
    return 0;
}

herr_t walkObject(hid_t file, const char* name, const H5O_info_t* info, void*) {
    const hid_t o = H5Oopen(file, name, H5P_DEFAULT);
    if (o < 0) return 0;
    H5Aiterate2(o, H5_INDEX_NAME, H5_ITER_NATIVE, nullptr, walkAttribute, nullptr);
    if (info->type == H5O_TYPE_DATASET) {
        const hid_t type = H5Dget_type(o), space = H5Dget_space(o);
        if (type >= 0 && space >= 0)
            readAll(type, space, [&](hid_t mem, void* buf) { return H5Dread(o, mem, H5S_ALL, H5S_ALL, H5P_DEFAULT, buf); });
        if (type >= 0) H5Tclose(type);
        if (space >= 0) H5Sclose(space);
    }
    H5Oclose(o);
    return 0;
}

}  // namespace

void collectHdf5Garbage() { H5garbage_collect(); }

bool hdf5LibrarySurvives(const std::string& path) {
    const pid_t child = ::fork();
    if (child < 0) {
        std::perror("eco fuzz: fork");
        std::abort();
    }
    if (child == 0) {
        // The child's crash is not a finding: no libFuzzer handler may save its input as one
        // (the death callback and the signal handlers are inherited), and its reports (ASan's
        // on HDF5's crash) stay out of the log.
        __sanitizer_set_death_callback(nullptr);
        // LLVM's OpenMP runtime registers every process as /dev/shm/__KMP_REGISTERED_LIB_<pid>_<uid>
        // (the child too) and removes the file only at a normal exit, which _exit and a crash
        // skip: one stale file per input (6000 after a few runs) unless removed here, first.
        char kmpName[64];
        std::snprintf(kmpName, sizeof kmpName, "/__KMP_REGISTERED_LIB_%d_%d", static_cast<int>(::getpid()),
                      static_cast<int>(::getuid()));
        ::shm_unlink(kmpName);
        for (const int sig : {SIGSEGV, SIGBUS, SIGABRT, SIGILL, SIGFPE, SIGALRM, SIGINT, SIGTERM, SIGXFSZ, SIGUSR1, SIGUSR2})
            ::signal(sig, SIG_DFL);
        const int devNull = ::open("/dev/null", O_WRONLY);
        if (devNull >= 0) ::dup2(devNull, 2);
        ::alarm(20);
        H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
        const hid_t f = H5Fopen(path.c_str(), H5F_ACC_RDONLY, H5P_DEFAULT);
        if (f >= 0) {
            H5Ovisit(f, H5_INDEX_NAME, H5_ITER_NATIVE, walkObject, nullptr);
            H5Fclose(f);
        }
        ::_exit(0);
    }
    int status = 0;
    while (::waitpid(child, &status, 0) < 0 && errno == EINTR) {
    }
    return WIFEXITED(status) && WEXITSTATUS(status) == 0;
}

}  // namespace eco::fuzz
