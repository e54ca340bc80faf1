// raylod gen teapot|bottle --triangles N [--around N] [-o FILE.ply|.stl] [--no-normals]
#include <cctype>
#include <cmath>
#include <cstdio>

#include "cli/cli.h"
#include "core/system.h"
#include "gen/generate.h"

namespace raylod::cli {
namespace {

// "1000000", "1e6", "2.5M", "30m", "1500k" (decimal multipliers: these are counts, not bytes).
StatusOr<uint64_t> parse_count(const std::string& text) {
  if (text.empty()) return Status::error("--triangles: empty value");
  std::string num = text;
  double mult = 1;
  const char last = char(std::tolower(static_cast<unsigned char>(text.back())));
  if (last == 'k' || last == 'm' || last == 'g') {
    mult = last == 'k' ? 1e3 : last == 'm' ? 1e6 : 1e9;
    num.pop_back();
  }
  try {
    size_t pos = 0;
    const double v = std::stod(num, &pos);
    if (pos != num.size() || !std::isfinite(v) || v <= 0) throw std::invalid_argument("bad");
    const double n = std::round(v * mult);
    if (n > 1e18) throw std::out_of_range("big");
    return uint64_t(n);
  } catch (...) {
    return Status::error("--triangles: '" + text + "' is not a triangle count (e.g. 1000000, 1e6, 10M)");
  }
}

std::string human_count(uint64_t n) {
  if (n >= 1000000 && n % 1000000 == 0) return std::to_string(n / 1000000) + "M";
  if (n >= 1000 && n % 1000 == 0) return std::to_string(n / 1000) + "k";
  return std::to_string(n);
}

int run_gen(int argc, char** argv) {
  Args args("gen", "teapot|bottle --triangles N [--around N] [-o FILE.ply|FILE.stl] [--no-normals]",
            "Writes a large CAD-like test mesh with analytic vertex normals, streamed to disk:\n"
            "  teapot  Newell's Utah teapot (32 bicubic Bezier patches), y up, base at y = 0\n"
            "  bottle  a glass bottle (closed surface of revolution with a 0.06 wall)\n"
            "The triangle count written is the closest the tessellation grid allows\n"
            "(usually within 0.1% of the request) and is printed.",
            {{"--triangles", "-n", "triangles to generate, 100 .. 1e9 (e.g. 1000000, 1e6, 10M; required)", true, "N"},
             {"--output", "-o", "output file, .ply (binary, indexed) or .stl (binary); default <shape>-<N>.ply",
              true, "FILE"},
             {"--no-normals", "", "omit vertex normals from the PLY", false, ""},
             {"--around", "", "bottle: columns around the axis (default: triangles close to square on the body)",
              true, "N"},
             quiet_option()});
  if (Status st = args.parse(argc, argv); !st) return fail("gen", st);
  if (args.help_requested()) {
    std::printf("%s", args.help_text().c_str());
    return 0;
  }
  if (args.positionals().size() != 1)
    return fail("gen", Status::error("expected one shape, teapot or bottle (see raylod gen --help)"));
  if (!args.has("--triangles")) return fail("gen", Status::error("--triangles N is required"));
  auto tri = parse_count(args.get("--triangles"));
  if (!tri) return fail("gen", tri.status());

  GenOptions options;
  options.shape = args.positionals()[0];
  options.triangles = *tri;
  options.normals = !args.has("--no-normals");
  auto around = args.get_int("--around", 0, 3, 0xffffffff);  // 0: the squarest grid
  if (!around) return fail("gen", around.status());
  options.around = uint32_t(*around);
  // A progress bar only where there is time to watch one.
  options.progress = !apply_quiet(args) && options.triangles >= 5000000;
  const std::string out = args.get("--output", options.shape + "-" + human_count(options.triangles) + ".ply");
  if (Status st = check_output_path(out, "the mesh (-o)"); !st) return fail("gen", st);
  auto report = generate_mesh(options, out);
  if (!report) return fail("gen", report.status());
  const GenReport& r = *report;
  summary("wrote %s\n", r.path.string().c_str());
  summary("  shape      %s (%s)\n", r.shape.c_str(), r.grid.c_str());
  summary("  triangles  %llu (requested %llu, %+.3f%%)\n", (unsigned long long)r.triangles,
              (unsigned long long)r.requested_triangles,
              100.0 * (double(r.triangles) - double(r.requested_triangles)) / double(r.requested_triangles));
  summary("  vertices   %llu%s\n", (unsigned long long)r.vertices,
              r.format == "stl" ? " (STL stores 3 per triangle)" : "");
  summary("  bytes      %llu (%s, %s)\n", (unsigned long long)r.bytes, format_bytes(r.bytes).c_str(),
              r.format == "ply" ? (options.normals ? "binary PLY with vertex normals" : "binary PLY")
                                : "binary STL with face normals");
  summary("  bounds     [%.4f %.4f %.4f] .. [%.4f %.4f %.4f]\n", r.bounds.lo.x, r.bounds.lo.y, r.bounds.lo.z,
              r.bounds.hi.x, r.bounds.hi.y, r.bounds.hi.z);
  summary("  seconds    %.2f (%.1f M triangles/s)\n", r.seconds, double(r.triangles) / r.seconds / 1e6);
  summary("  peak RSS   %s\n", format_bytes(peak_rss_bytes()).c_str());
  return 0;
}

}  // namespace

RAYLOD_COMMAND("gen", "write a large test mesh (teapot or bottle) with analytic normals", run_gen);

}  // namespace raylod::cli
