#!/bin/bash
# eco ensemble on a Slurm cluster (docs/ensemble.md): one MPI rank per member at a time,
# each rank with the cores Slurm gives its task. Submit from the repository root:
#   sbatch docs/ensemble-slurm.sh configs/ensemble.toml
# A job that reaches its time limit gets SIGTERM first (--signal): the running members stop
# after their simulation year with a checkpoint; submitting the same script again skips the
# finished members and resumes the others. out_dir must be on a file system every node sees.
#SBATCH --job-name=eco-ensemble
#SBATCH --ntasks=8               # ranks: members run at once
#SBATCH --cpus-per-task=4        # OpenMP threads of each rank (within a member)
#SBATCH --time=02:00:00
#SBATCH --signal=TERM@120        # SIGTERM two minutes before the limit
#SBATCH --output=eco-ensemble-%j.log
set -euo pipefail
spec=${1:?usage: sbatch docs/ensemble-slurm.sh SPEC.toml}
export OMP_NUM_THREADS=${SLURM_CPUS_PER_TASK:-1}
export OMP_PROC_BIND=close OMP_PLACES=cores
# srun starts the ranks through PMIx (OpenMPI from Debian is built with it); with an
# mpirun-only installation use: mpirun -n "$SLURM_NTASKS" ./build/apps/eco ensemble "$spec"
srun --mpi=pmix ./build/apps/eco ensemble "$spec"
