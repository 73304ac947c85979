// The processes of one eco ensemble run: one process, or the ranks of an MPI job (mpirun,
// srun). Only what the ensemble needs: who am I, a string from rank 0 to all, a wait for all.
#pragma once

#include <memory>
#include <string>

namespace eco::cli {

class ProcessGroup {
public:
    virtual ~ProcessGroup() = default;
    virtual int rank() const { return 0; }
    virtual int size() const { return 1; }
    /// Processes of the group on this machine (for the threads each one uses).
    virtual int localSize() const { return 1; }
    /// `value` of rank 0, on every rank.
    virtual std::string broadcast(const std::string& value) { return value; }
    virtual void barrier() {}
};

/// True when this process was started by an MPI launcher (its environment says so).
bool launchedByMpi();
/// This build has MPI (OpenMPI from Debian, found when it was configured).
bool haveMpi();
/// The group of this process: MPI's world when launched by MPI, else a group of one. One for
/// the life of the process: MPI is initialised at the first call and finalised when the
/// process exits (MPI may be initialised only once, and eco calibrate runs an ensemble per
/// evaluation). ExitStatus (usage) when launched by MPI and this build has no MPI: every rank
/// would run every member.
ProcessGroup& joinProcessGroup();

}  // namespace eco::cli
