// The MPI work pool (built when Open MPI is found): a shared counter on rank 0 that every rank
// increments with MPI_Fetch_and_op (passive target, so rank 0 works like the others), then the
// results gathered to every rank.
#include <mpi.h>

#include <cstdint>
#include <cstring>
#include <mutex>
#include <thread>

#include "mvtwin/core/error.h"
#include "mvtwin/studies/work_pool.h"

namespace mvtwin::studies {
namespace {

void check(int rc, const char* what) {
  if (rc != MPI_SUCCESS) {
    char msg[MPI_MAX_ERROR_STRING];
    int len = 0;
    MPI_Error_string(rc, msg, &len);
    throw Error(std::string("MPI: ") + what +
                " failed: " + std::string(msg, static_cast<std::size_t>(len)));
  }
}

class MpiPool final : public WorkPool {
 public:
  MpiPool() {
    int initialized = 0;
    MPI_Initialized(&initialized);
    if (!initialized) {
      int provided = 0;
      check(MPI_Init_thread(nullptr, nullptr, MPI_THREAD_SERIALIZED, &provided), "MPI_Init_thread");
      owns_ = true;
      serialized_ = provided >= MPI_THREAD_SERIALIZED;
    }
    MPI_Comm_set_errhandler(MPI_COMM_WORLD, MPI_ERRORS_RETURN);
    MPI_Comm_rank(MPI_COMM_WORLD, &rank_);
    MPI_Comm_size(MPI_COMM_WORLD, &size_);
  }
  ~MpiPool() override {
    if (owns_) MPI_Finalize();
  }
  int rank() const override { return rank_; }
  int size() const override { return size_; }
  void barrier() override { check(MPI_Barrier(MPI_COMM_WORLD), "MPI_Barrier"); }

  std::vector<std::string> map(int n, int threads,
                               const std::function<std::string(int)>& work) override {
    // The counter: one 64-bit integer on rank 0.
    std::int64_t* base = nullptr;
    MPI_Win win;
    check(MPI_Win_allocate(rank_ == 0 ? sizeof(std::int64_t) : 0, sizeof(std::int64_t),
                           MPI_INFO_NULL, MPI_COMM_WORLD, &base, &win),
          "MPI_Win_allocate");
    if (rank_ == 0) {
      MPI_Win_lock(MPI_LOCK_EXCLUSIVE, 0, 0, win);
      *base = 0;
      MPI_Win_unlock(0, win);
    }
    barrier();
    check(MPI_Win_lock_all(0, win), "MPI_Win_lock_all");
    std::mutex mpi;  // MPI_THREAD_SERIALIZED: one thread in MPI at a time
    auto next = [&]() -> int {
      std::lock_guard<std::mutex> lock(mpi);
      const std::int64_t one = 1;
      std::int64_t got = 0;
      check(MPI_Fetch_and_op(&one, &got, MPI_INT64_T, 0, 0, MPI_SUM, win), "MPI_Fetch_and_op");
      check(MPI_Win_flush(0, win), "MPI_Win_flush");
      return static_cast<int>(got);
    };
    std::vector<std::pair<int, std::string>> mine;
    std::mutex mine_mutex;
    auto worker = [&] {
      for (int i; (i = next()) < n;) {
        std::string r = work(i);
        std::lock_guard<std::mutex> lock(mine_mutex);
        mine.emplace_back(i, std::move(r));
      }
    };
    const int nt = serialized_ ? std::max(1, threads) : 1;
    std::vector<std::thread> pool;
    for (int t = 1; t < nt; ++t) pool.emplace_back(worker);
    worker();
    for (auto& t : pool) t.join();
    MPI_Win_unlock_all(win);
    barrier();
    MPI_Win_free(&win);

    // Gather: each rank packs (index, length, bytes) records; every rank receives all.
    std::string packed;
    for (const auto& [i, s] : mine) {
      const std::int64_t head[2] = {i, static_cast<std::int64_t>(s.size())};
      packed.append(reinterpret_cast<const char*>(head), sizeof head);
      packed += s;
    }
    int len = static_cast<int>(packed.size());
    std::vector<int> lens(static_cast<std::size_t>(size_)), displs(static_cast<std::size_t>(size_));
    check(MPI_Allgather(&len, 1, MPI_INT, lens.data(), 1, MPI_INT, MPI_COMM_WORLD),
          "MPI_Allgather");
    std::size_t total = 0;
    for (int r = 0; r < size_; ++r) {
      displs[static_cast<std::size_t>(r)] = static_cast<int>(total);
      total += static_cast<std::size_t>(lens[static_cast<std::size_t>(r)]);
    }
    std::string all(total, '\0');
    check(MPI_Allgatherv(packed.data(), len, MPI_CHAR, all.data(), lens.data(), displs.data(),
                         MPI_CHAR, MPI_COMM_WORLD),
          "MPI_Allgatherv");
    std::vector<std::string> out(static_cast<std::size_t>(std::max(0, n)));
    for (std::size_t at = 0; at + 2 * sizeof(std::int64_t) <= all.size();) {
      std::int64_t head[2];
      std::memcpy(head, all.data() + at, sizeof head);
      at += sizeof head;
      out[static_cast<std::size_t>(head[0])] = all.substr(at, static_cast<std::size_t>(head[1]));
      at += static_cast<std::size_t>(head[1]);
    }
    return out;
  }

 private:
  int rank_ = 0, size_ = 1;
  bool owns_ = false, serialized_ = true;
};

}  // namespace

bool built_with_mpi() { return true; }

std::unique_ptr<WorkPool> make_pool_from_environment() {
  if (!launched_by_mpi()) return make_local_pool();
  return std::make_unique<MpiPool>();
}

}  // namespace mvtwin::studies
