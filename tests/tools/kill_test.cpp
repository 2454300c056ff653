// Kill-safe batches (issue 15): `simulate`, `calibrate`, `import` and a cohort study are killed
// with SIGKILL at moments spread over their run (a fixed generator, so the same moments on every
// run of the test), then checked: each output file is absent, the previous complete version or
// the new complete version (read back by its reader, compared with an uninterrupted run's);
// no temporary is left once the command has run again; a resumed study ends with the numbers
// of an uninterrupted one and redoes no patient it had finished.
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <random>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "mvtwin/core/calibration_file.h"
#include "mvtwin/core/patient_file.h"
#include "mvtwin/core/simulation_file.h"

namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

struct Outcome {
  bool killed = false;   ///< still running at the deadline, and killed
  int exit_code = -1;    ///< when it ended by itself
  double seconds = 0.0;  ///< until it ended or was killed
};

class KillSafe : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("mvtwin_kill_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }

  /// What `watched` looks like now (size and change time, or absent) and whether any
  /// temporary of it exists: the first write changes one or the other.
  std::string snapshot(const std::string& watched) const {
    std::error_code ec;
    std::string s = std::to_string(temporaries_of(watched));
    if (fs::exists(watched, ec)) {
      s += " " + std::to_string(fs::file_size(watched, ec)) + " " +
           std::to_string(fs::last_write_time(watched, ec).time_since_epoch().count());
    }
    return s;
  }

  /// Runs mvtwin with args (output to log.txt), killing it with SIGKILL after `deadline_s`
  /// (never, if negative), or, with `watched`, `deadline_s` after the command first touches
  /// that file or creates a temporary of it: the moment a file is being written, which random
  /// moments over the whole run would rarely hit.
  Outcome run(const std::vector<std::string>& args, double deadline_s = -1.0,
              const std::string& watched = "") {
    const std::string log = path("log.txt");
    std::cout.flush();  // or the child would print the parent's buffered lines again
    std::fflush(nullptr);
    const auto t0 = Clock::now();
    const pid_t pid = ::fork();
    if (pid == 0) {
      std::FILE* f = std::freopen(log.c_str(), "w", stdout);
      if (f) ::dup2(::fileno(stdout), 2);
      std::vector<char*> argv;
      std::string bin = MVTWIN_BINARY;
      argv.push_back(bin.data());
      std::vector<std::string> copy = args;
      for (std::string& a : copy) argv.push_back(a.data());
      argv.push_back(nullptr);
      ::execv(bin.c_str(), argv.data());
      ::_exit(127);
    }
    Outcome r;
    int status = 0;
    const std::string before = watched.empty() ? "" : snapshot(watched);
    double touched_at = watched.empty() ? 0.0 : -1.0;
    for (;;) {
      const pid_t w = ::waitpid(pid, &status, WNOHANG);
      r.seconds = std::chrono::duration<double>(Clock::now() - t0).count();
      if (w == pid) {
        r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
        return r;
      }
      if (touched_at < 0.0 && snapshot(watched) != before) touched_at = r.seconds;
      if (deadline_s >= 0.0 && touched_at >= 0.0 && r.seconds >= touched_at + deadline_s) {
        ::kill(pid, SIGKILL);
        ::waitpid(pid, &status, 0);
        r.killed = WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL;
        if (!r.killed) r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
        return r;
      }
      std::this_thread::sleep_for(std::chrono::microseconds(watched.empty() ? 2000 : 100));
    }
  }
  std::string log() const {
    std::ifstream f(dir_ / "log.txt");
    std::stringstream s;
    s << f.rdbuf();
    return s.str();
  }
  /// Temporaries of finished or killed writers beside `file`.
  int temporaries_of(const std::string& file) const {
    int n = 0;
    const std::string prefix = "." + fs::path(file).filename().string() + ".tmp-";
    std::error_code ec;
    for (fs::directory_iterator it(fs::path(file).parent_path(), ec), end; !ec && it != end;
         it.increment(ec))
      n += it->path().filename().string().rfind(prefix, 0) == 0;
    return n;
  }

  /// Kills `args` (which write `out`) at `kills` moments drawn uniformly over 1.1 times the
  /// uninterrupted run's `full_s` (every other run: 0-5 ms after it starts writing `out`), each
  /// time starting from `previous` (copied over `out`, or no
  /// file when empty); `version(out)` names what is there: "previous", "new" or anything else
  /// (a failure). Returns how many runs were killed before they ended.
  int kill_repeatedly(const std::vector<std::string>& args, const std::string& out,
                      const std::string& previous, double full_s, int kills, unsigned seed,
                      const std::function<std::string(const std::string&)>& version) {
    std::mt19937 gen(seed);
    std::uniform_real_distribution<double> when(0.0, 1.1 * full_s);
    int killed = 0, saw_previous = 0, saw_new = 0, saw_none = 0;
    for (int k = 0; k < kills; ++k) {
      std::error_code ec;
      fs::remove(out, ec);
      if (!previous.empty()) fs::copy_file(previous, out);
      // Every other run is killed while the output is being written: 0-5 ms after the first
      // change to it or its temporary.
      const bool at_write = k % 2 == 1;
      const double at = at_write ? 0.005 * when(gen) / (1.1 * full_s) : when(gen);
      const Outcome r = run(args, at, at_write ? out : "");
      killed += r.killed;
      if (!r.killed) {
        EXPECT_EQ(r.exit_code, 0) << "run " << k << ":\n" << log();
      }
      if (!fs::exists(out)) {
        EXPECT_TRUE(previous.empty())
            << "run " << k << " killed at " << at << " s: the previous file is gone";
        ++saw_none;
        continue;
      }
      const std::string v = version(out);
      EXPECT_TRUE(v == "new" || (v == "previous" && !previous.empty()))
          << "run " << k << " killed at " << at << " s left " << v;
      saw_previous += v == "previous";
      saw_new += v == "new";
    }
    std::cout << fs::path(out).filename().string() << ": " << kills << " runs, " << killed
              << " killed (uninterrupted " << full_s << " s); afterwards " << saw_previous
              << " previous, " << saw_new << " new, " << saw_none << " absent\n";
    // The next complete run removes what the killed ones left behind.
    EXPECT_EQ(run(args).exit_code, 0) << log();
    EXPECT_EQ(temporaries_of(out), 0) << "temporaries of killed writers beside " << out;
    return killed;
  }

  fs::path dir_;
};

bool same_surfaces(const mvtwin::SimulationRecord& a, const mvtwin::SimulationRecord& b) {
  if (a.la_surface.size() != b.la_surface.size() || a.la_surface.empty()) return false;
  return a.la_surface.back().points() == b.la_surface.back().points() && a.time_s == b.time_s &&
         a.status == b.status;
}

TEST_F(KillSafe, SimulateLeavesThePreviousOrTheNewFile) {
#ifdef __SANITIZE_ADDRESS__
  GTEST_SKIP() << "closures take too long under AddressSanitizer";
#endif
  ASSERT_EQ(run({"phantom", "--seed", "3", "--out", path("p.h5")}).exit_code, 0) << log();
  // Unsettled (settle_mm=0): what is killed is the writing, which does not depend on the
  // settling at rest; it took 70 % of each closure (1.8 s instead of 0.5).
  const std::vector<std::string> grid = {"--set",  "ures=16", "--set",
                                         "vres=8", "--set",   "settle_mm=0"};
  auto simulate = [&](const std::string& out, std::vector<std::string> extra) {
    std::vector<std::string> a = {"simulate", path("p.h5"), "--out", out, "--force"};
    a.insert(a.end(), grid.begin(), grid.end());
    a.insert(a.end(), extra.begin(), extra.end());
    return a;
  };
  ASSERT_EQ(run(simulate(path("previous.h5"), {"--set", "peak_pressure_mmhg=60"})).exit_code, 0)
      << log();
  const Outcome full = run(simulate(path("new.h5"), {}));
  ASSERT_EQ(full.exit_code, 0) << log();
  const auto prev = mvtwin::read_simulation_file(path("previous.h5"));
  const auto next = mvtwin::read_simulation_file(path("new.h5"));
  ASSERT_FALSE(same_surfaces(prev, next));
  auto version = [&](const std::string& f) -> std::string {
    try {
      const auto r = mvtwin::read_simulation_file(f);
      return same_surfaces(r, next) ? "new" : same_surfaces(r, prev) ? "previous" : "other";
    } catch (const std::exception& e) {
      return std::string("unreadable: ") + e.what();
    }
  };
  const std::string out = path("out.h5");
  EXPECT_GT(
      kill_repeatedly(simulate(out, {}), out, path("previous.h5"), full.seconds, 12, 1, version),
      6);
  EXPECT_GT(kill_repeatedly(simulate(out, {}), out, "", full.seconds, 6, 2, version), 3);
}

TEST_F(KillSafe, CalibrateLeavesThePreviousOrTheNewFile) {
#ifdef __SANITIZE_ADDRESS__
  GTEST_SKIP() << "calibrations take too long under AddressSanitizer";
#endif
  ASSERT_EQ(
      run({"phantom", "--seed", "4", "--simulate-closure", "--quick", "--out", path("obs.h5")})
          .exit_code,
      0)
      << log();
  auto calibrate = [&](const std::string& out, const std::string& sims) {
    return std::vector<std::string>{"calibrate",   path("obs.h5"),
                                    "--fit",       "restlength_factor_anterolateral_marginal",
                                    "--no-scan",   "--max-sims",
                                    sims,          "--set",
                                    "ures=16",     "--set",
                                    "vres=8",      "--set",
                                    "settle_mm=0",  // unsettled, as in the test above
                                    "--out",       out,
                                    "--force"};
  };
  ASSERT_EQ(run(calibrate(path("previous.h5"), "3")).exit_code, 0) << log();
  const Outcome full = run(calibrate(path("new.h5"), "6"));
  ASSERT_EQ(full.exit_code, 0) << log();
  const auto prev = mvtwin::read_calibration_file(path("previous.h5"));
  const auto next = mvtwin::read_calibration_file(path("new.h5"));
  ASSERT_NE(prev.simulations, next.simulations);
  auto version = [&](const std::string& f) -> std::string {
    try {
      const auto c = mvtwin::read_calibration_file(f);
      if (c.simulations == next.simulations && c.fitted == next.fitted) return "new";
      if (c.simulations == prev.simulations && c.fitted == prev.fitted) return "previous";
      return "other";
    } catch (const std::exception& e) {
      return std::string("unreadable: ") + e.what();
    }
  };
  const std::string out = path("out.h5");
  EXPECT_GT(
      kill_repeatedly(calibrate(out, "6"), out, path("previous.h5"), full.seconds, 8, 3, version),
      4);
}

TEST_F(KillSafe, ImportLeavesThePreviousOrTheNewFile) {
#ifdef __SANITIZE_ADDRESS__
  GTEST_SKIP() << "the import's fit takes too long under AddressSanitizer";
#endif
  ASSERT_EQ(run({"phantom", "--seed", "4", "--simulate-closure", "--quick", "--out", path("v.h5")})
                .exit_code,
            0)
      << log();
  const mvtwin::Patient v = mvtwin::read_patient(path("v.h5"));
  const int ed = v.sequence.end_diastole, fc = v.sequence.first_closed;
  ASSERT_EQ(run({"export", path("v.h5"), "--labelmap", path("seg"), "--convention", "mvseg",
                 "--voxel", "0.8", "--frames", std::to_string(ed) + "," + std::to_string(fc)})
                .exit_code,
            0)
      << log();
  char name[64], t_ed[32], t_fc[32];
  std::snprintf(name, sizeof name, "seg/frame_%02d.nii.gz", ed);
  const std::string f_ed = path(name);
  std::snprintf(name, sizeof name, "seg/frame_%02d.nii.gz", fc);
  const std::string f_fc = path(name);
  std::snprintf(name, sizeof name, "seg/tips_%02d.mrk.json", ed);
  const std::string m_ed = path(name);
  std::snprintf(t_ed, sizeof t_ed, "%.4f", v.sequence.frames[ed].time_s);
  std::snprintf(t_fc, sizeof t_fc, "%.4f", v.sequence.frames[fc].time_s);
  auto import = [&](const std::string& out, bool closed) {
    std::vector<std::string> a = {"import", "--convention", "mvseg", "--frame", f_ed + "@" + t_ed};
    if (closed) a.insert(a.end(), {"--frame", f_fc + "@" + t_fc});
    a.insert(a.end(), {"--markups", m_ed + "@" + t_ed, "--out", out, "--force"});
    return a;
  };
  ASSERT_EQ(run(import(path("previous.h5"), false)).exit_code, 0) << log();
  const Outcome full = run(import(path("new.h5"), true));
  ASSERT_EQ(full.exit_code, 0) << log();
  const mvtwin::Patient prev = mvtwin::read_patient(path("previous.h5"));
  const mvtwin::Patient next = mvtwin::read_patient(path("new.h5"));
  ASSERT_NE(prev.sequence.frames.size(), next.sequence.frames.size());
  auto same = [](const mvtwin::Patient& a, const mvtwin::Patient& b) {
    if (a.sequence.frames.size() != b.sequence.frames.size()) return false;
    for (size_t k = 0; k < a.sequence.frames.size(); ++k) {
      const auto &fa = a.sequence.frames[k].la_surface, &fb = b.sequence.frames[k].la_surface;
      if (fa.has_value() != fb.has_value() || (fa && fa->points() != fb->points())) return false;
    }
    return true;
  };
  auto version = [&](const std::string& f) -> std::string {
    try {
      const mvtwin::Patient p = mvtwin::read_patient(f);
      return same(p, next) ? "new" : same(p, prev) ? "previous" : "other";
    } catch (const std::exception& e) {
      return std::string("unreadable: ") + e.what();
    }
  };
  const std::string out = path("out.h5");
  EXPECT_GT(
      kill_repeatedly(import(out, true), out, path("previous.h5"), full.seconds, 8, 4, version), 4);
}

/// The numbers of a cohort study (not its times).
nlohmann::json numbers_of(const fs::path& study_json) {
  std::ifstream f(study_json);
  const nlohmann::json study = nlohmann::json::parse(f);
  nlohmann::json out = nlohmann::json::array();
  for (const auto& p : study["patients"])
    out.push_back({p["id"], p["status"], p["error_default_mm"], p["orifice_mm2"],
                   p["coaptation_mm"], p["rating"], p["error_calibrated_mm"]});
  return out;
}

TEST_F(KillSafe, KilledCohortStudyResumesToTheSameNumbersRedoingNothingFinished) {
#ifdef __SANITIZE_ADDRESS__
  GTEST_SKIP() << "studies take too long under AddressSanitizer";
#endif
  auto study = [&](const std::string& out) {
    return std::vector<std::string>{"study",   "cohort",    "--quick", "--patients", "3",
                                    "--cache", path("obs"), "--out",   out};
  };
  // The first run simulates the observations into the cache; the second, timed, reads them.
  ASSERT_EQ(run(study(path("first"))).exit_code, 0) << log();
  const Outcome full = run(study(path("whole")));
  ASSERT_EQ(full.exit_code, 0) << log();
  const nlohmann::json whole = numbers_of(dir_ / "whole" / "study.json");
  ASSERT_EQ(whole.size(), 3u);
  // Killed again and again at moments spread over the run, each time resumed from what the
  // killed runs left; then run to the end.
  std::mt19937 gen(5);
  std::uniform_real_distribution<double> when(0.4 * full.seconds, 0.95 * full.seconds);
  const fs::path out = dir_ / "killed";
  int killed = 0;
  for (int k = 0; k < 6; ++k) {
    auto count_records = [&] {
      int n = 0;
      if (fs::is_directory(out / "records"))
        for (const auto& e : fs::directory_iterator(out / "records"))
          n += e.path().extension() == ".json";
      return n;
    };
    const int before = count_records();
    // Every other run is killed 0-5 ms after it first writes into records/ (a patient's record
    // being written), the others at a moment between 40 and 95 % of the run.
    const bool at_write = k % 2 == 1;
    const double at = when(gen);
    const Outcome r =
        at_write ? run(study(out.string()), 0.005 * at / full.seconds, (out / "records").string())
                 : run(study(out.string()), at);
    killed += r.killed;
    if (!r.killed) {
      EXPECT_EQ(r.exit_code, 0) << log();
      break;
    }
    // Every record left behind is complete JSON.
    if (!fs::is_directory(out / "records")) continue;
    for (const auto& e : fs::directory_iterator(out / "records")) {
      if (e.path().extension() != ".json") continue;
      std::ifstream f(e.path());
      EXPECT_TRUE(nlohmann::json::accept(f)) << e.path();
    }
    std::cout << "cohort run " << k << " killed after " << r.seconds << " s: " << before << " -> "
              << count_records() << " patients finished\n";
  }
  EXPECT_GT(killed, 0);
  int finished = 0;
  if (fs::is_directory(out / "records"))
    for (const auto& e : fs::directory_iterator(out / "records"))
      finished += e.path().extension() == ".json";
  const Outcome last = run(study(out.string()));
  ASSERT_EQ(last.exit_code, 0) << log();
  const std::string text = log();
  int resumed = 0;
  for (size_t at = text.find("resumed"); at != std::string::npos; at = text.find("resumed", at + 1))
    ++resumed;
  EXPECT_EQ(resumed, finished) << "each patient finished before the kills is resumed, not redone\n"
                               << text;
  EXPECT_EQ(numbers_of(out / "study.json"), whole);
  EXPECT_EQ(temporaries_of((out / "study.json").string()), 0);
}

}  // namespace
