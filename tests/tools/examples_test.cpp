// Every example in every command's --help, run as written (MFEM-style sample runs): in one
// scratch folder, in the order of a session (a later example uses what an earlier one made),
// in-process through the same parser and commands as the mvtwin executable. Examples marked
// "# long" are parsed (their options must exist and be valid) but not run.
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <iostream>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "commands.h"
#include "exit_codes.h"

namespace {

namespace fs = std::filesystem;

struct Example {
  std::string line;  ///< "mvtwin simulate patient.h5 --out closed.h5"
  bool long_run = false;
};

/// Splits a command line as a POSIX shell would for these examples: blanks separate words,
/// double quotes group.
std::vector<std::string> split_words(const std::string& line) {
  std::vector<std::string> words;
  std::string w;
  bool quoted = false, any = false;
  for (char c : line) {
    if (c == '"') {
      quoted = !quoted;
      any = true;
    } else if (!quoted && (c == ' ' || c == '\t')) {
      if (any) words.push_back(w);
      w.clear();
      any = false;
    } else {
      w += c;
      any = true;
    }
  }
  if (any) words.push_back(w);
  return words;
}

/// The example lines of a footer: lines "  mvtwin ..." (or "  mpirun -np N mvtwin ...", run
/// as one process), a trailing "# comment" dropped; "# long..." marks a long run.
std::vector<Example> examples_in(const std::string& footer) {
  std::vector<Example> out;
  std::istringstream lines(footer);
  for (std::string l; std::getline(lines, l);) {
    if (l.rfind("  ", 0) != 0) continue;
    std::string text = l.substr(2);
    bool long_run = false;
    if (text.rfind("mpirun ", 0) == 0) {
      const auto at = text.find(" mvtwin ");
      if (at == std::string::npos) continue;
      text = text.substr(at + 1);
      long_run = true;  // many ranks: parsed only
    }
    if (text.rfind("mvtwin ", 0) != 0) continue;
    if (const auto hash = text.find("  #"); hash != std::string::npos) {
      const std::string comment = text.substr(text.find_first_not_of(" #", hash));
      long_run = long_run || comment.rfind("long", 0) == 0;
      text = text.substr(0, hash);
    }
    while (!text.empty() && text.back() == ' ') text.pop_back();
    out.push_back({text, long_run});
  }
  return out;
}

void collect(const CLI::App* app, const std::string& prefix, std::vector<std::string>* leaves,
             std::map<std::string, std::vector<Example>>* examples) {
  for (const CLI::App* sub : app->get_subcommands({})) {
    const std::string name = prefix.empty() ? sub->get_name() : prefix + " " + sub->get_name();
    if (sub->get_subcommands({}).empty()) {
      leaves->push_back(name);
      (*examples)[name] = examples_in(sub->get_footer());
    } else {
      collect(sub, name, leaves, examples);
    }
  }
}

/// Every leaf command of mvtwin (into *leaves) with the examples of its --help.
std::map<std::string, std::vector<Example>> help_examples(std::vector<std::string>* leaves) {
  CLI::App app{"mvtwin"};
  mvtwin::tools::Context ctx;
  mvtwin::tools::add_commands(app, ctx);
  std::map<std::string, std::vector<Example>> examples;
  collect(&app, "", leaves, &examples);
  return examples;
}

/// Parses `line` with a fresh mvtwin application; runs the command unless `parse_only`.
int run_line(const std::string& line, bool parse_only) {
  CLI::App app{"mvtwin"};
  app.require_subcommand(1);
  mvtwin::tools::Context ctx;
  ctx.command_line = line;
  mvtwin::tools::add_commands(app, ctx);
  std::vector<std::string> words = split_words(line);
  std::vector<const char*> argv;
  for (const auto& w : words) argv.push_back(w.c_str());
  try {
    app.parse(static_cast<int>(argv.size()), argv.data());
  } catch (const CLI::ParseError& e) {
    ADD_FAILURE() << line << ": the command line is refused: " << e.what();
    return mvtwin::tools::kExitUsage;
  }
  if (!ctx.run) {
    ADD_FAILURE() << line << ": no command chosen";
    return mvtwin::tools::kExitUsage;
  }
  if (parse_only) return mvtwin::tools::kExitOk;
  try {
    return ctx.run();
  } catch (const std::exception& e) {
    ADD_FAILURE() << line << ": " << e.what();
    return mvtwin::tools::kExitInput;
  }
}

/// The order of a session: every command in it, each after what its examples read.
const std::vector<std::string> kSession = {"phantom",
                                           "cohort",
                                           "export",
                                           "import",
                                           "export-model",
                                           "simulate",
                                           "tune-chordae",
                                           "distance",
                                           "calibrate",
                                           "info",
                                           "clip",
                                           "render-tee",
                                           "train-detector",
                                           "detect",
                                           "bench closure",
                                           "bench solvers",
                                           "bench import",
                                           "study cohort",
                                           "study sensitivity",
                                           "study convergence",
                                           "study clip",
                                           "study robustness",
                                           "study detection"};

TEST(HelpExamples, EveryCommandHasExamplesAndTheSessionListsEveryCommand) {
  std::vector<std::string> leaves;
  const std::map<std::string, std::vector<Example>> examples = help_examples(&leaves);
  EXPECT_EQ(std::set<std::string>(leaves.begin(), leaves.end()),
            std::set<std::string>(kSession.begin(), kSession.end()))
      << "a command is missing from kSession (or kSession names one that is gone)";
  for (const std::string& c : leaves) {
    const auto& ex = examples.at(c);
    EXPECT_TRUE(std::any_of(ex.begin(), ex.end(), [](const Example& e) { return !e.long_run; }))
        << "mvtwin " << c << " --help shows no example that the tests can run";
    for (const Example& e : ex)
      EXPECT_EQ(e.line.rfind("mvtwin " + c + " ", 0), 0u) << c << "'s help shows " << e.line;
  }
}

TEST(HelpExamples, EveryExampleRunsAsWritten) {
#ifdef __SANITIZE_ADDRESS__
  GTEST_SKIP() << "the examples simulate, calibrate, train and run studies: too long under "
                  "AddressSanitizer (the other tests run the same code)";
#endif
  std::vector<std::string> leaves;
  const std::map<std::string, std::vector<Example>> examples = help_examples(&leaves);

  const fs::path home = fs::current_path();
  const fs::path dir = fs::temp_directory_path() / ("mvtwin_examples_" + std::to_string(getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  fs::current_path(dir);
  int ran = 0, parsed = 0;
  for (const std::string& c : kSession) {
    for (const Example& e : examples.at(c)) {
      SCOPED_TRACE(e.line);
      std::cout << "[example] " << e.line << (e.long_run ? "   (long: parsed only)" : "")
                << std::endl;
      const auto start = std::chrono::steady_clock::now();
      const int status = run_line(e.line, e.long_run);
      if (!e.long_run)
        std::cout << "[example] "
                  << std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count()
                  << " s" << std::endl;
      EXPECT_EQ(status, mvtwin::tools::kExitOk) << e.line;
      (e.long_run ? parsed : ran) += 1;
    }
  }
  std::cout << "[example] " << ran << " examples run, " << parsed << " long ones parsed\n";
  fs::current_path(home);
  if (!HasFailure()) fs::remove_all(dir);
}

}  // namespace
