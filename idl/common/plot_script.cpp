#include "common/plot_script.hpp"

#include <spawn.h>
#include <sys/wait.h>

#include <cstdio>
#include <vector>

extern char** environ;

namespace common {

bool run_plot_script(const std::string& tool, const std::string& script_name, const std::filesystem::path& dir,
                     const std::string& title) {
  const std::filesystem::path script = std::filesystem::path(CELL_SOURCE_DIR) / "bin" / script_name;
  std::vector<std::string> args = {"/usr/bin/python3", script.string(), dir.string(), "--title", title};
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  pid_t pid = 0;
  int status = 0;
  const int err = posix_spawn(&pid, argv[0], nullptr, nullptr, argv.data(), environ);
  const bool ok = err == 0 && waitpid(pid, &status, 0) == pid && WIFEXITED(status) && WEXITSTATUS(status) == 0;
  if (!ok)
    std::fprintf(stderr, "%s: plotting failed (%s %s); the tables are in %s\n", tool.c_str(), args[0].c_str(),
                 script.c_str(), dir.c_str());
  return ok;
}

}  // namespace common
