// The project's plots are drawn by Python scripts in bin/ with Debian's matplotlib
// (/usr/bin/python3): every tool that plots runs them through this one function.
#pragma once

#include <filesystem>
#include <string>

namespace common {

// Runs /usr/bin/python3 bin/<script_name> DIR --title TITLE as an argument vector, never a
// shell (a title comes from a scenario's name and may hold quotes). Returns whether it
// succeeded; says in one line on stderr (prefixed by `tool`) when it did not.
bool run_plot_script(const std::string& tool, const std::string& script_name, const std::filesystem::path& dir,
                     const std::string& title);

}  // namespace common
