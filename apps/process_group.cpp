#include "process_group.h"

#include <cstdlib>
#include <vector>

#include "cli_common.h"

#ifdef ECO_HAVE_MPI
#include <mpi.h>
#endif

namespace eco::cli {

bool launchedByMpi() {
    // OpenMPI's mpirun, a PMIx or PMI launcher (srun, MPICH's mpiexec).
    for (const char* v : {"OMPI_COMM_WORLD_SIZE", "PMIX_RANK", "PMI_RANK", "PMI_SIZE"})
        if (std::getenv(v)) return true;
    return false;
}

#ifdef ECO_HAVE_MPI
bool haveMpi() { return true; }

namespace {

class MpiGroup : public ProcessGroup {
public:
    MpiGroup() {
        MPI_Init(nullptr, nullptr);
        MPI_Comm_rank(MPI_COMM_WORLD, &rank_);
        MPI_Comm_size(MPI_COMM_WORLD, &size_);
        MPI_Comm local;
        MPI_Comm_split_type(MPI_COMM_WORLD, MPI_COMM_TYPE_SHARED, rank_, MPI_INFO_NULL, &local);
        MPI_Comm_size(local, &localSize_);
        MPI_Comm_free(&local);
    }
    ~MpiGroup() override { MPI_Finalize(); }
    MpiGroup(const MpiGroup&) = delete;
    MpiGroup& operator=(const MpiGroup&) = delete;
    int rank() const override { return rank_; }
    int size() const override { return size_; }
    int localSize() const override { return localSize_; }
    std::string broadcast(const std::string& value) override {
        int n = static_cast<int>(value.size());
        MPI_Bcast(&n, 1, MPI_INT, 0, MPI_COMM_WORLD);
        std::vector<char> buf(value.begin(), value.end());
        buf.resize(static_cast<std::size_t>(n));
        if (n > 0) MPI_Bcast(buf.data(), n, MPI_CHAR, 0, MPI_COMM_WORLD);
        return std::string(buf.begin(), buf.end());
    }
    void barrier() override { MPI_Barrier(MPI_COMM_WORLD); }

private:
    int rank_ = 0, size_ = 1, localSize_ = 1;
};

}  // namespace

static std::unique_ptr<ProcessGroup> makeProcessGroup() {
    if (launchedByMpi()) return std::make_unique<MpiGroup>();
    return std::make_unique<ProcessGroup>();
}
#else
bool haveMpi() { return false; }

static std::unique_ptr<ProcessGroup> makeProcessGroup() {
    if (launchedByMpi())
        throw ExitStatus(2, "ensemble: started by an MPI launcher, but this eco was built without MPI (install "
                            "libopenmpi-dev and configure again); every rank would run every member");
    return std::make_unique<ProcessGroup>();
}
#endif

ProcessGroup& joinProcessGroup() {
    // Destroyed (MPI finalised) when the process exits.
    static const std::unique_ptr<ProcessGroup> group = makeProcessGroup();
    return *group;
}

}  // namespace eco::cli
