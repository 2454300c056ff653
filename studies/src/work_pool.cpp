#include "mvtwin/studies/work_pool.h"

#include <atomic>
#include <cstdlib>
#include <thread>

#include "mvtwin/core/error.h"

namespace mvtwin::studies {
namespace {

class LocalPool final : public WorkPool {
 public:
  int rank() const override { return 0; }
  int size() const override { return 1; }
  std::vector<std::string> map(int n, int threads,
                               const std::function<std::string(int)>& work) override {
    std::vector<std::string> out(static_cast<std::size_t>(std::max(0, n)));
    std::atomic<int> next{0};
    auto worker = [&] {
      for (int i; (i = next++) < n;) out[static_cast<std::size_t>(i)] = work(i);
    };
    const int nt = std::max(1, std::min(threads, n));
    std::vector<std::thread> pool;
    for (int t = 1; t < nt; ++t) pool.emplace_back(worker);
    worker();
    for (auto& t : pool) t.join();
    return out;
  }
  void barrier() override {}
};

int env_int(const char* name) {
  const char* v = std::getenv(name);
  return v ? std::atoi(v) : -1;
}

}  // namespace

std::string WorkPool::describe() const {
  if (size() == 1 && !built_with_mpi()) return "1 process";
  return std::to_string(size()) + (size() == 1 ? " process" : " MPI ranks");
}

std::unique_ptr<WorkPool> make_local_pool() { return std::make_unique<LocalPool>(); }

bool launched_by_mpi() {
  return env_int("OMPI_COMM_WORLD_SIZE") > 0 || env_int("PMIX_RANK") >= 0 ||
         env_int("PMI_RANK") >= 0 || env_int("PMI_SIZE") > 0;
}

#ifndef MVTWIN_WITH_MPI
bool built_with_mpi() { return false; }

std::unique_ptr<WorkPool> make_pool_from_environment() {
  const int size = std::max(env_int("OMPI_COMM_WORLD_SIZE"), env_int("PMI_SIZE"));
  if (launched_by_mpi() && size > 1)
    throw Error("this mvtwin was built without MPI, but was started by mpirun with " +
                std::to_string(size) +
                " ranks (each would run the whole study): install libopenmpi-dev and rebuild, "
                "or run without mpirun");
  return make_local_pool();
}
#endif

}  // namespace mvtwin::studies
