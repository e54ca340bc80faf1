// The `raylod` command line: one executable, one file per subcommand
// (cmd_<name>.cpp), each registering itself with RAYLOD_COMMAND.
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "core/memory_budget.h"
#include "core/status.h"
#include "core/system.h"
#include "probe/probe.h"
#include "scene/scene.h"

namespace raylod::cli {

// Minimal option parser: "--name value", "--name=value", "-o value", flags,
// and positionals. Unknown options are errors.
class Args {
 public:
  struct Option {
    std::string name;       // "--rays"
    std::string alias;      // "-o" or ""
    std::string help;       // "test rays to trace (default 5000)"
    bool takes_value = true;
    std::string metavar = "VALUE";
  };
  Args(std::string command, std::string usage, std::string description, std::vector<Option> options);

  // Parses argv (after the subcommand name). Returns an error for unknown
  // options or missing values; sets help_requested() for -h/--help.
  Status parse(int argc, char** argv);
  bool help_requested() const { return help_; }
  std::string help_text() const;

  bool has(const std::string& name) const { return values_.count(name) != 0; }
  std::string get(const std::string& name, const std::string& fallback = "") const;
  StatusOr<int64_t> get_int(const std::string& name, int64_t fallback, int64_t lo, int64_t hi) const;
  StatusOr<double> get_double(const std::string& name, double fallback) const;
  // Sizes like 1G or 512M (see parse_size); fallback when absent.
  StatusOr<uint64_t> get_size(const std::string& name, uint64_t fallback) const;
  const std::vector<std::string>& positionals() const { return positionals_; }

 private:
  std::string command_, usage_, description_;
  std::vector<Option> options_;
  std::map<std::string, std::string> values_;
  std::vector<std::string> positionals_;
  bool help_ = false;
};

struct Command {
  const char* name;
  const char* summary;
  int (*run)(int argc, char** argv);  // argv[0] is the subcommand name
};

bool register_command(const Command& command);
const std::vector<Command>& commands();

// The --crease-angle option (degrees, 0 to 180) that commands which shade
// meshes without normals share; `fallback` when it is absent.
// A number as a help line states it: 25, 22.5 (%g).
std::string format_degrees(double deg);
// Its help line states kDefaultCreaseAngleDeg, so it cannot go stale.
std::string crease_angle_help();
StatusOr<double> crease_angle_from_args(const Args& args, double fallback);

// The cut options `raylod probe` and `raylod run` share (probe.h): the
// criterion, its tolerance in pixels and K, with one set of defaults.
std::vector<Args::Option> cut_options();
// `options` followed by cut_options().
std::vector<Args::Option> with_cut_options(std::vector<Args::Option> options);
struct CutOptions {
  CutCriterion criterion = CutCriterion::Deviation;
  double tolerance_px = kDefaultTolerancePx;
  double angle_tolerance_px = kDefaultAngleTolerancePx;
  double outline_tolerance = kDefaultOutlineTolerance;  // a fraction of tolerance_px
  // Unreached mirror and glass cells' bound, a multiple of angle_tolerance_px.
  double unreached_angle_allowance = kDefaultUnreachedAngleAllowance;
  double footprint_scale = kDefaultFootprintScale;
  CutBalance balance = CutBalance::Specular;
  bool unseen_cells = true;      // --unseen-cells on or frustum
  bool shadow_receivers = true;  // --unseen-cells on
  bool tolerance_given = false, angle_tolerance_given = false;
  // The default tolerances for a render of `spp` samples per pixel
  // (default_tolerance_px), where none was given.
  void fit_defaults_to(int spp) {
    if (!tolerance_given) tolerance_px = default_tolerance_px(spp);
    if (!angle_tolerance_given) angle_tolerance_px = default_angle_tolerance_px(spp);
  }
};
StatusOr<CutOptions> cut_options_from_args(const Args& args);

// --stats-json FILE, if given: checked before any work (its folder exists and
// it is not a folder), so that a bad path does not fail a finished run.
Status check_stats_json_path(const Args& args);
// The mesh files a scene-reading command reads: --mesh and every object's.
std::vector<FileRole> scene_mesh_files(const Args& args, const Scene& scene);
// The files a scene-reading command reads: the scene file (if given) and
// scene_mesh_files, for check_outputs_apart (core/system.h).
std::vector<FileRole> scene_input_files(const Args& args, const Scene& scene);

// The scene named by the single positional argument, or the embedded default
// scene when there is none (more than one positional is an error), with
// --crease-angle applied if the command has it and it was given.
StatusOr<Scene> scene_from_args(const Args& args);

// --threads T: how many threads the whole command may use. Commands that run
// parallel stages list threads_option() (help text, and so that parsing
// accepts it); main() reads the value with threads_from_argv before the
// command runs and creates the process's one tbb::global_control from it.
// The stages create no thread limit of their own (core/parallelism.h).
Args::Option threads_option(const std::string& note = "");
// The value of --threads among a command's arguments (argv[0] is the
// subcommand name; the last occurrence wins, as in Args::parse): 0, meaning
// all cores, when absent; an error unless it is an integer from 0 to 4096.
StatusOr<int> threads_from_argv(int argc, char** argv);

// --memory-limit, resolved once at the command line boundary: the size given,
// else the default, a quarter of physical memory (MemoryBudget::resolve).
// Commands pass its total down as a concrete number; inside the library 0
// means no limit (memory_budget.h). `raylod render` alone defaults to no limit.
StatusOr<MemoryBudget> memory_budget_from_args(const Args& args);

// --quiet / -q means the same on every command that takes it: no progress
// bars, no log lines and no summary, only errors and warnings (on stderr).
// Files the command writes (images, --stats-json) are written as without it.
Args::Option quiet_option();
// Reads --quiet from args: turns the progress bars off and the summary()
// lines with them. Returns whether it was given.
bool apply_quiet(const Args& args);
// A line of the summary a command prints on stdout when it is done
// (printf-style); nothing under --quiet.
void summary(const char* format, ...) __attribute__((format(printf, 1, 2)));

// Prints "raylod <cmd>: <message>" to stderr and returns the exit code 1.
int fail(const char* command, const Status& status);

}  // namespace raylod::cli

#define RAYLOD_COMMAND(name, summary, fn) \
  static const bool raylod_command_registered_##fn = ::raylod::cli::register_command({name, summary, fn})
