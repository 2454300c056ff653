#pragma once
// The processes a study runs on: this one, or the ranks of an MPI job (mpirun, srun).
#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace mvtwin::studies {

class WorkPool {
 public:
  virtual ~WorkPool() = default;
  virtual int rank() const = 0;
  virtual int size() const = 0;
  bool is_root() const { return rank() == 0; }
  /// "1 process" or "4 MPI ranks".
  std::string describe() const;

  /// Runs work(i) once for every i in [0, n) over all the pool's processes. Balancing is
  /// dynamic: a process (or one of its `threads`) that finishes an item takes the next one not
  /// yet started, so items of different lengths spread evenly. Every process returns all n
  /// results in index order. `work` must not throw (record a failure in its result instead):
  /// an exception would leave the other ranks waiting.
  virtual std::vector<std::string> map(int n, int threads,
                                       const std::function<std::string(int)>& work) = 0;
  /// Every process waits for the others.
  virtual void barrier() = 0;
};

/// One process: map runs `threads` items at a time.
std::unique_ptr<WorkPool> make_local_pool();

/// True when this process was started by an MPI launcher (mpirun, mpiexec or srun).
bool launched_by_mpi();
/// Whether this build has MPI (MVTWIN_WITH_MPI: Open MPI found at configure time).
bool built_with_mpi();

/// The ranks of MPI_COMM_WORLD when launched by an MPI launcher and built with MPI (MPI is
/// initialized here and finalized when the pool is destroyed), else a local pool. Throws
/// mvtwin::Error when launched by mpirun with more than one rank in a build without MPI
/// (every rank would run the whole study).
std::unique_ptr<WorkPool> make_pool_from_environment();

}  // namespace mvtwin::studies
