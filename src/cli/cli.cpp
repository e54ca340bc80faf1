#include "cli/cli.h"

#include <cctype>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <optional>
#include <sstream>

#include "core/cluster.h"
#include "core/progress.h"
#include "core/system.h"

namespace raylod::cli {

Args::Args(std::string command, std::string usage, std::string description, std::vector<Option> options)
    : command_(std::move(command)), usage_(std::move(usage)), description_(std::move(description)),
      options_(std::move(options)) {}

Status Args::parse(int argc, char** argv) {
  for (int i = 1; i < argc; ++i) {
    std::string a = argv[i];
    if (a == "-h" || a == "--help") { help_ = true; continue; }
    if (a.size() > 1 && a[0] == '-' && !(a.size() > 1 && (std::isdigit(static_cast<unsigned char>(a[1])) || a[1] == '.'))) {
      std::string name = a, value;
      bool inline_value = false;
      if (auto eq = a.find('='); eq != std::string::npos && a.rfind("--", 0) == 0) {
        name = a.substr(0, eq);
        value = a.substr(eq + 1);
        inline_value = true;
      }
      const Option* opt = nullptr;
      for (const auto& o : options_) if (o.name == name || (!o.alias.empty() && o.alias == name)) opt = &o;
      if (!opt) return Status::error("unknown option '" + name + "' (see raylod " + command_ + " --help)");
      if (opt->takes_value) {
        if (!inline_value) {
          if (i + 1 >= argc) return Status::error("option " + opt->name + " needs a value");
          value = argv[++i];
        }
        values_[opt->name] = value;
      } else {
        if (inline_value) return Status::error("option " + opt->name + " takes no value");
        values_[opt->name] = "1";
      }
    } else {
      positionals_.push_back(a);
    }
  }
  return {};
}

std::string Args::help_text() const {
  std::ostringstream out;
  out << "usage: raylod " << command_ << " " << usage_ << "\n\n" << description_ << "\n";
  if (!options_.empty()) {
    out << "\noptions:\n";
    for (const auto& o : options_) {
      std::string left = "  " + (o.alias.empty() ? "" : o.alias + ", ") + o.name + (o.takes_value ? " " + o.metavar : "");
      if (left.size() < 30) left.resize(30, ' ');
      else left += "\n" + std::string(30, ' ');
      out << left << o.help << "\n";
    }
  }
  out << "  -h, --help                  show this help\n";
  return out.str();
}

std::string Args::get(const std::string& name, const std::string& fallback) const {
  auto it = values_.find(name);
  return it == values_.end() ? fallback : it->second;
}

StatusOr<int64_t> Args::get_int(const std::string& name, int64_t fallback, int64_t lo, int64_t hi) const {
  if (!has(name)) return fallback;
  const std::string text = get(name);
  try {
    size_t pos = 0;
    long long v = std::stoll(text, &pos);
    if (pos != text.size()) throw std::invalid_argument("trailing");
    if (v < lo || v > hi)
      return Status::error(name + " must be between " + std::to_string(lo) + " and " + std::to_string(hi));
    return int64_t(v);
  } catch (...) {
    return Status::error(name + ": '" + text + "' is not an integer");
  }
}

StatusOr<double> Args::get_double(const std::string& name, double fallback) const {
  if (!has(name)) return fallback;
  const std::string text = get(name);
  try {
    size_t pos = 0;
    double v = std::stod(text, &pos);
    if (pos != text.size() || !std::isfinite(v)) throw std::invalid_argument("bad");
    return v;
  } catch (...) {
    return Status::error(name + ": '" + text + "' is not a number");
  }
}

StatusOr<uint64_t> Args::get_size(const std::string& name, uint64_t fallback) const {
  if (!has(name)) return fallback;
  auto v = parse_size(get(name));
  if (!v) return v.status().with_context(name);
  return v;
}

static std::vector<Command>& registry() {
  static std::vector<Command> r;
  return r;
}
bool register_command(const Command& c) {
  registry().push_back(c);
  return true;
}
const std::vector<Command>& commands() { return registry(); }

std::string format_degrees(double deg) {
  char text[32];
  std::snprintf(text, sizeof text, "%g", deg);
  return text;
}

std::string crease_angle_help() {
  return "shade facets meeting at more than DEG degrees as a crease, for meshes\n"
         "                              without normals (default: the scene's crease_angle, " +
         format_degrees(kDefaultCreaseAngleDeg) + ")";
}

StatusOr<double> crease_angle_from_args(const Args& args, double fallback) {
  if (!args.has("--crease-angle")) return fallback;
  RAYLOD_ASSIGN_OR_RETURN(double deg, args.get_double("--crease-angle", fallback));
  if (!(deg >= 0 && deg <= 180)) return Status::error("--crease-angle must be between 0 and 180 degrees");
  return deg;
}

std::vector<Args::Option> cut_options() {
  char k[256], tol[200], angle[400], outline[300], unreached[400];
  std::snprintf(k, sizeof k, "K: cells may collapse while their diagonal < K x footprint\n"
                "                              (default %g; %g with --criterion diagonal)",
                kDefaultFootprintScale, kDefaultDiagonalFootprintScale);
  std::snprintf(tol, sizeof tol,
                "deviation criterion: largest surface deviation a collapse may cause,\n"
                "                              in pixels (default %g; less above 4 spp)", kDefaultTolerancePx);
  std::snprintf(angle, sizeof angle,
                "deviation criterion on mirrors and glass: largest turn of a reflected\n"
                "                              or refracted ray, in pixel angles, where test rays measured it\n"
                "                              (default %g; %g times it where none reached, --unreached-angle;\n"
                "                              less above 4 spp)",
                kDefaultAngleTolerancePx, kDefaultUnreachedAngleAllowance);
  std::snprintf(unreached, sizeof unreached,
                "deviation criterion on mirrors and glass, where no test ray reached:\n"
                "                              this many times --angle-tolerance (default %g; larger trades\n"
                "                              accuracy for fewer triangles, README \"What accuracy costs\")",
                kDefaultUnreachedAngleAllowance);
  std::snprintf(outline, sizeof outline,
                "deviation criterion where an outline may run: this fraction of\n"
                "                              --tolerance, 0 to 1 (default %g; 1: the same as elsewhere)",
                kDefaultOutlineTolerance);
  return {{"--criterion", "", "which cells collapse: deviation (default; bounded surface and\n"
                              "                              mirror-normal error) or diagonal (the paper's K test alone)", true, "NAME"},
          {"--tolerance", "", tol, true, "PX"},
          {"--angle-tolerance", "", angle, true, "PX"},
          {"--outline-tolerance", "", outline, true, "F"},
          {"--unreached-angle", "", unreached, true, "F"},
          {"--footprint-scale", "", k, true, "K"},
          {"--balance", "", "grade the cut (no cell beside one two levels coarser): specular\n"
                            "                              (objects on mirrors and glass under the deviation criterion;\n"
                            "                              default), all or off", true, "WHICH"},
          {"--unseen-cells", "", "on (default), frustum or off: cells no test ray reached that the\n"
                                 "                              camera cannot see (back faces of a closed mesh, outside the\n"
                                 "                              view) and whose shadows fall on nothing it sees collapse;\n"
                                 "                              frustum: their shadows count wherever they may fall in the\n"
                                 "                              view (the rule before 2026-11-30); off: the rule before\n"
                                 "                              2026-11-29", true, "ON|FRUSTUM|OFF"}};
}

std::vector<Args::Option> with_cut_options(std::vector<Args::Option> options) {
  for (auto& o : cut_options()) options.push_back(std::move(o));
  return options;
}

StatusOr<CutOptions> cut_options_from_args(const Args& args) {
  CutOptions o;
  if (args.has("--criterion")) { RAYLOD_ASSIGN_OR_RETURN(o.criterion, parse_cut_criterion(args.get("--criterion"))); }
  o.tolerance_given = args.has("--tolerance");
  o.angle_tolerance_given = args.has("--angle-tolerance");
  RAYLOD_ASSIGN_OR_RETURN(o.tolerance_px, args.get_double("--tolerance", kDefaultTolerancePx));
  if (!(o.tolerance_px > 0)) return Status::error("--tolerance must be > 0 (pixels)");
  RAYLOD_ASSIGN_OR_RETURN(o.angle_tolerance_px, args.get_double("--angle-tolerance", kDefaultAngleTolerancePx));
  if (!(o.angle_tolerance_px > 0)) return Status::error("--angle-tolerance must be > 0 (pixel angles)");
  RAYLOD_ASSIGN_OR_RETURN(o.outline_tolerance, args.get_double("--outline-tolerance", kDefaultOutlineTolerance));
  if (!(o.outline_tolerance > 0 && o.outline_tolerance <= 1))
    return Status::error("--outline-tolerance must be a fraction of --tolerance, greater than 0 and at most 1");
  RAYLOD_ASSIGN_OR_RETURN(o.unreached_angle_allowance,
                          args.get_double("--unreached-angle", kDefaultUnreachedAngleAllowance));
  if (!(o.unreached_angle_allowance > 0) || !std::isfinite(o.unreached_angle_allowance))
    return Status::error("--unreached-angle must be a finite multiple of --angle-tolerance, greater than 0");
  const bool outline_given = args.has("--outline-tolerance");
  const bool unreached_given = args.has("--unreached-angle");
  if (o.criterion == CutCriterion::Diagonal &&
      (o.tolerance_given || o.angle_tolerance_given || outline_given || unreached_given))
    return Status::error(std::string(o.tolerance_given         ? "--tolerance"
                                     : o.angle_tolerance_given ? "--angle-tolerance"
                                     : outline_given           ? "--outline-tolerance"
                                                               : "--unreached-angle") +
                         " bounds the deviation criterion; --criterion diagonal compares cell diagonals with K "
                         "footprints alone (--footprint-scale)");
  const double default_k =
      o.criterion == CutCriterion::Diagonal ? kDefaultDiagonalFootprintScale : kDefaultFootprintScale;
  RAYLOD_ASSIGN_OR_RETURN(o.footprint_scale, args.get_double("--footprint-scale", default_k));
  if (!(o.footprint_scale > 0)) return Status::error("--footprint-scale must be > 0");
  if (args.has("--balance")) { RAYLOD_ASSIGN_OR_RETURN(o.balance, parse_cut_balance(args.get("--balance"))); }
  if (args.has("--unseen-cells")) {
    const std::string v = args.get("--unseen-cells");
    if (v != "on" && v != "frustum" && v != "off")
      return Status::error("--unseen-cells: unknown value '" + v + "' (on, frustum or off)");
    o.unseen_cells = v != "off";
    o.shadow_receivers = v == "on";
  }
  return o;
}

Status check_stats_json_path(const Args& args) {
  if (!args.has("--stats-json")) return {};
  return check_output_path(args.get("--stats-json"), "--stats-json");
}

std::vector<FileRole> scene_mesh_files(const Args& args, const Scene& scene) {
  std::vector<FileRole> files;
  if (args.has("--mesh")) files.push_back({args.get("--mesh"), "the --mesh file"});
  for (size_t i = 0; i < scene.objects.size(); ++i)
    files.push_back({scene.objects[i].mesh, "the mesh of objects[" + std::to_string(i) + "]"});
  return files;
}

std::vector<FileRole> scene_input_files(const Args& args, const Scene& scene) {
  std::vector<FileRole> files;
  if (!args.positionals().empty()) files.push_back({args.positionals()[0], "the scene file"});
  // A mesh of a glTF file is named "FILE.glb#meshes[N]": the file is the input.
  for (FileRole& mesh : scene_mesh_files(args, scene)) files.push_back({parse_mesh_ref(mesh.path).file, mesh.role});
  return files;
}

StatusOr<Scene> scene_from_args(const Args& args) {
  if (args.positionals().size() > 1) return Status::error("expected at most one SCENE argument");
  RAYLOD_ASSIGN_OR_RETURN(Scene scene, args.positionals().empty() ? default_scene() : load_scene(args.positionals()[0], args.has("--mesh")));
  RAYLOD_ASSIGN_OR_RETURN(scene.crease_angle_deg, crease_angle_from_args(args, scene.crease_angle_deg));
  return scene;
}

StatusOr<MemoryBudget> memory_budget_from_args(const Args& args) {
  std::optional<uint64_t> given;
  if (args.has("--memory-limit")) {
    RAYLOD_ASSIGN_OR_RETURN(given, args.get_size("--memory-limit", 0));
    if (*given < kMinMemoryLimit)
      return Status::error("--memory-limit: '" + args.get("--memory-limit") +
                           "' is less than 1M, the least any command accepts");
  }
  return MemoryBudget::resolve(given);
}

Args::Option threads_option(const std::string& note) {
  return {"--threads", "", "worker threads for the whole command (default 0: all cores)" + note, true, "T"};
}

StatusOr<int> threads_from_argv(int argc, char** argv) {
  // The same reading of the arguments as Args::parse: "--threads T" or
  // "--threads=T", the last one counting.
  std::optional<std::string> text;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--threads") {
      if (i + 1 >= argc) return Status::error("option --threads needs a value");
      text = argv[++i];
    } else if (a.rfind("--threads=", 0) == 0) {
      text = a.substr(std::string("--threads=").size());
    }
  }
  if (!text) return 0;
  Args parsed("", "", "", {threads_option()});
  std::string name = "--threads";
  char* values[] = {name.data(), name.data(), text->data()};
  RAYLOD_RETURN_IF_ERROR(parsed.parse(3, values));
  RAYLOD_ASSIGN_OR_RETURN(int64_t threads, parsed.get_int("--threads", 0, 0, 4096));
  return int(threads);
}

namespace {
bool g_quiet = false;
}  // namespace

Args::Option quiet_option() {
  return {"--quiet", "-q", "no progress bars, log lines or summary: errors and warnings only", false, ""};
}

bool apply_quiet(const Args& args) {
  g_quiet = args.has("--quiet");
  if (g_quiet) Progress::set_enabled(false);
  return g_quiet;
}

void summary(const char* format, ...) {
  if (g_quiet) return;
  va_list values;
  va_start(values, format);
  std::vprintf(format, values);
  va_end(values);
}

int fail(const char* command, const Status& status) {
  // Under mpirun the ranks settle the failure first; rank 0 prints it.
  const std::optional<Status> shown =
      cluster::settle_failure(status, std::string("raylod ") + command + ": error: ");
  if (shown) std::fprintf(cluster::error_output(), "raylod %s: error: %s\n", command, shown->message().c_str());
  return 1;
}

}  // namespace raylod::cli
