// raylod simplify STORE CUT -o OUT.drc|.ply|.obj [--memory-limit SIZE]
// Method step A5: collapse the cut's cells to their QEM representative
// vertices and write the simplified mesh.
#include <algorithm>
#include <cctype>
#include <chrono>
#include <filesystem>
#include <cmath>
#include <cstdio>
#include <string>

#include <glm/gtc/matrix_transform.hpp>

#include "cli/cli.h"
#include "core/system.h"
#include "pipeline/pipeline.h"
#include "probe/probe.h"
#include "simplify/collapse.h"
#include "simplify/indexed_mesh_writer.h"
#include "streaming/cut_file.h"
#include "streaming/draco_io.h"
#include "streaming/gltf_io.h"
#include "streaming/octree_store.h"

namespace raylod::cli {
namespace {

std::string lower_extension(const std::filesystem::path& p) {
  std::string e = p.extension().string();
  for (char& c : e) c = char(std::tolower(static_cast<unsigned char>(c)));
  return e;
}

StatusOr<DracoWriteReport> write_simplified_glb(const std::filesystem::path& out, IndexedMesh&& mesh,
                                                const DracoOptions& options) {
  const Vec3d origin = mesh.origin;
  RAYLOD_ASSIGN_OR_RETURN(DracoEncoded encoded, encode_draco(out, std::move(mesh), options));
  DracoWriteReport report = encoded.report;
  std::vector<GlbMesh> meshes(1);
  meshes[0].name = out.stem().string();
  // A part file's parts become the primitives of the one glTF mesh.
  RAYLOD_ASSIGN_OR_RETURN(const auto parts, draco_parts(encoded.bytes.data(), encoded.bytes.size(), out.string()));
  meshes[0].draco.assign(parts[0].begin(), parts[0].end());
  for (size_t p = 1; p < parts.size(); ++p) meshes[0].more_parts.emplace_back(parts[p].begin(), parts[p].end());
  RAYLOD_ASSIGN_OR_RETURN(report.bytes, write_glb(out, meshes, {GlbNode{meshes[0].name, 0, glm::translate(glm::dmat4(1.0), origin)}}));
  return report;
}

unsigned long long ull(uint64_t v) { return static_cast<unsigned long long>(v); }

int run_simplify(int argc, char** argv) {
  Args args("simplify", "STORE CUT -o OUT.drc|OUT.glb|OUT.ply|OUT.obj [options]",
            "Collapses every cell of the cut (from `raylod probe`) to its representative vertex\n"
            "(minimum of the cell's quadric, kept inside the cell), keeps all other vertices exactly,\n"
            "drops triangles that become degenerate or duplicated, and writes the simplified mesh\n"
            "with vertex normals. Draco positions are quantised so that the error stays below 1/8\n"
            "of the smallest footprint the probe measured and below what tilts a face of the\n"
            "input's mean size by 1/510 rad (override with --position-error). A cut from\n"
            "`raylod probe` records what `raylod run` would simplify it with (fold passes, exact\n"
            "normals, normal bits, crease angle), and those are the defaults: by hand, the same mesh.",
            {{"--output", "-o", "output mesh: .drc (Draco), .glb (glTF with a Draco primitive), .ply (binary)\n"
                                  "                              or .obj (required)", true, "FILE"},
             {"--memory-limit", "", "memory the simplified mesh may use (default: a quarter of RAM)", true, "SIZE"},
             {"--position-error", "", "Draco: largest position error in world units (default: as the pipeline's)",
              true, "E"},
             {"--normal-bits", "", "Draco: octahedral normal quantisation bits, 2..24 (default: as raylod run,\n"
                                   "                              from the scene's materials, recorded in the cut; else 10)", true, "N"},
             {"--speed", "", "Draco: encoder speed 0 (smallest) .. 10 (fastest) (default 5)", true, "S"},
             {"--parts", "", "Draco: split the mesh into N bitstreams encoded and decoded in parallel\n"
                             "                              (.drc: a raylod part file, which other Draco tools do not read;\n"
                             "                              .glb: N primitives) (default 1; raylod run uses one per million\n"
                             "                              triangles from 2M)", true, "N"},
             {"--crease-angle", "", std::string("normals: facets meeting at more than DEG degrees keep separate\n"
                                                "                              normals (default ") +
                                        format_degrees(kDefaultCreaseAngleDeg) + ", or the scene's crease_angle the cut records; meshes without\n"
                                                "                              normals: one with its own keeps the default)", true, "DEG"},
             {"--fold-passes", "", "passes that refine cells whose collapse turns a triangle over\n"
                                   "                              (default: as raylod run, 3 on mirror and glass meshes, 0 on others,\n"
                                   "                              recorded in the cut; else 0)", true, "N"},
             {"--exact-normals", "", "a representative takes the normal the full render shades at the input\n"
                                     "                              point nearest it: the input's, or without normals the crease rule's\n"
                                     "                              (within a degree of the cell's mean; by default where there are\n"
                                     "                              fold passes and the cut records raylod run's settings, as run does)",
              false, ""},
             {"--no-unfold", "", "leave turned-over triangles as the collapse made them (by default their\n"
                                 "                              representatives slide, or their edges collapse, within the\n"
                                 "                              cells' deviation)", false, ""},
             quiet_option()});
  if (Status st = args.parse(argc, argv); !st) return fail("simplify", st);
  if (args.help_requested()) {
    std::printf("%s", args.help_text().c_str());
    return 0;
  }
  if (args.positionals().size() != 2)
    return fail("simplify", Status::error("expected STORE and CUT (see raylod simplify --help)"));
  if (!args.has("--output")) return fail("simplify", Status::error("-o OUT.drc|.glb|.ply|.obj is required"));
  const std::filesystem::path store_path = args.positionals()[0], cut_path = args.positionals()[1];
  const std::filesystem::path out_path = args.get("--output");
  const std::string ext = lower_extension(out_path);
  if (ext != ".drc" && ext != ".glb" && ext != ".ply" && ext != ".obj")
    return fail("simplify", Status::error(out_path.string() + ": unknown output format '" + ext +
                                          "' (use .drc, .glb, .ply or .obj)"));
  if (Status st = check_output_path(out_path, "the simplified mesh (-o)"); !st) return fail("simplify", st);
  auto limit = memory_budget_from_args(args);
  if (!limit) return fail("simplify", limit.status());
  auto normal_bits = args.get_int("--normal-bits", 0, 2, kMaxNormalBits);
  if (!normal_bits) return fail("simplify", normal_bits.status());
  auto speed = args.get_int("--speed", 5, 0, 10);
  if (!speed) return fail("simplify", speed.status());
  auto parts = args.get_int("--parts", 1, 1, 256);
  if (!parts) return fail("simplify", parts.status());
  auto fold_passes = args.get_int("--fold-passes", -1, 0, 64);
  if (!fold_passes) return fail("simplify", fold_passes.status());
  auto position_error = args.get_double("--position-error", 0);
  if (!position_error) return fail("simplify", position_error.status());
  if (args.has("--position-error") && !(*position_error > 0))  // 0 (not given): the pipeline's bound
    return fail("simplify", Status::error("--position-error must be positive"));

  using Clock = std::chrono::steady_clock;
  auto since = [](Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); };
  const auto t_open = Clock::now();
  auto store = OctreeStore::open(store_path);
  if (!store) return fail("simplify", store.status());
  auto cut = read_cut(cut_path);
  if (!cut) return fail("simplify", cut.status());
  if (cut->store_hash != store_fingerprint(**store)) {
    // The same file (the path the cut recorded) rebuilt or built from a
    // changed mesh since, or another store altogether.
    std::error_code ec;
    const bool same_file = std::filesystem::equivalent(cut->store_path, store_path, ec);
    const std::string why =
        same_file ? "the store " + store_path.string() +
                        " has changed since the cut was made (rebuilt, or its mesh changed: the mesh's size, time "
                        "and content hash, and the store's layout, are part of the cut's fingerprint)"
                  : "the cut was made for a different store (" + cut->store_path + "), not " + store_path.string();
    return fail("simplify", Status::error(cut_path.string() + ": " + why + "; run raylod probe on this store"));
  }

  if (Status st = check_outputs_apart({{out_path, "the simplified mesh (-o)"}},
                                      {{store_path, "the store"},
                                       {cut_path, "the cut"},
                                       {(*store)->header().source_path, "the store's mesh"}});
      !st)
    return fail("simplify", st);
  // Refuse before any work if the output would not fit.
  const SimplifyEstimate estimate = estimate_simplify(**store, *cut);
  if (estimate.bytes > limit->total)
    return fail("simplify", Status::error("the simplified mesh (about " + std::to_string(estimate.triangles) +
                                          " triangles) needs about " + format_bytes(estimate.bytes) +
                                          ", over the memory limit of " + format_bytes(limit->total) +
                                          "; nothing was written. Raise --memory-limit or probe with a larger "
                                          "--footprint-scale"));

  const double open_seconds = since(t_open);
  // Unless given, what raylod run uses for this store, as the probe recorded
  // it in the cut (simplify_settings_of; a cut from before: the defaults).
  const SimplifySettings pipeline = simplify_settings_of(*cut);
  auto crease = crease_angle_from_args(args, pipeline.crease_angle_deg);
  if (!crease) return fail("simplify", crease.status());
  SimplifyConfig config;
  config.crease_angle_deg = *crease;
  config.memory_limit = limit->total;
  config.fold_passes = args.has("--fold-passes") ? int(*fold_passes) : pipeline.fold_passes;
  config.exact_normals =
      args.has("--exact-normals") || (pipeline.recorded && exact_normals_for(config.fold_passes));
  config.unfold = !args.has("--no-unfold");
  config.progress = !apply_quiet(args);
  auto result = simplify(**store, *cut, config);
  if (!result) return fail("simplify", result.status().with_context(store_path.string()));
  SimplifyResult& r = *result;  // its mesh is handed to the writer
  if (r.mesh.triangle_count() == 0)
    return fail("simplify", Status::error((*store)->header().source_path + ": " + why_simplified_mesh_is_empty(r, *cut) +
                                          "; nothing was written"));

  const auto t_write = Clock::now();
  uint64_t bytes = 0;
  std::string quantisation;
  if (ext == ".drc" || ext == ".glb") {
    DracoOptions opt;
    opt.normal_bits = args.has("--normal-bits") ? int(*normal_bits) : pipeline.normal_bits;
    opt.speed = int(*speed);
    opt.parts = int(*parts);
    // The bound `raylod run` uses for the same cut (pipeline.h), so that this
    // command writes the mesh run would cache.
    const double bound = draco_error_bound(*cut, **store);
    opt.max_position_error = *position_error > 0 ? *position_error
                                                 : thin_wall_position_bound(bound, r.mesh, (*store)->header().root_size,
                                                                            config.exact_normals);
    // .glb: the same Draco bytes as the .drc, as one primitive of one node.
    auto report = ext == ".drc" ? write_draco(out_path, std::move(r.mesh), opt)
                                  : write_simplified_glb(out_path, std::move(r.mesh), opt);
    if (!report) return fail("simplify", report.status());
    bytes = report->bytes;
    char line[256];
    std::snprintf(line, sizeof line,
                  "  draco      position %d bits (max error %.3g, target %.3g), normal %d bits (max %.3g deg)\n",
                  report->position_bits, report->max_position_error, report->requested_position_error,
                  report->normal_bits, report->max_normal_error * 180.0 / M_PI);
    quantisation = line;
    if (*position_error > 0 && report->max_position_error > *position_error)
      std::fprintf(stderr,
                   "raylod simplify: warning: --position-error %.3g cannot be met: the decoded positions are floats, "
                   "whose rounding bounds the error at %.3g here (%d bits)\n",
                   *position_error, report->max_position_error, report->position_bits);
  } else {
    Status st = ext == ".ply" ? write_indexed_ply(out_path, r.mesh) : write_indexed_obj(out_path, r.mesh);
    if (!st) return fail("simplify", st);
    std::error_code ec;
    bytes = std::filesystem::file_size(out_path, ec);
  }

  const double write_seconds = since(t_write);
  const CollapseStats& s = r.stats;
  summary("wrote %s\n", out_path.string().c_str());
  summary("  triangles  %llu of %llu (%.2f%%)\n", ull(s.output_triangles), ull(s.input_triangles),
              s.input_triangles ? 100.0 * double(s.output_triangles) / double(s.input_triangles) : 0.0);
  summary("  vertices   %llu (%llu representatives, %llu of them cells of one vertex output as kept; %llu kept, %llu "
              "more where corners meet at a crease)\n",
              ull(s.output_vertices), ull(s.representatives_used), ull(s.one_vertex_cells), ull(s.kept_vertices),
              ull(s.split_vertices));
  summary("  cut        %llu cells (%llu not in the store), %llu representatives clamped to their cell\n",
              ull(r.cut_cells), ull(r.cut_cells_missing), ull(r.clamped_representatives));
  summary("  dropped    %llu collapsed (%llu inside one cell), %llu zero-area, %llu duplicate; %llu reverse-wound "
              "twins kept\n",
              ull(s.dropped_collapsed), ull(s.inside_cell), ull(s.dropped_zero_area), ull(s.dropped_duplicate),
              ull(s.reverse_twins));
  if (r.fold_passes || s.folded)
    summary("  folds      %llu cells refined in %llu more passes for triangles turned over; %llu turned over\n",
            ull(r.fold_cells_refined), ull(r.fold_passes), ull(s.folded));
  if (s.folded_before_unfold)
    summary("  unfolded   %llu slides and %llu merges (%llu triangles fewer): %llu -> %llu turned over\n",
            ull(s.unfold_moved), ull(s.unfold_merged), ull(s.unfold_dropped), ull(s.folded_before_unfold),
            ull(s.folded_after_unfold));
  if (r.fold_passes_undone)
    summary("  folds      a refinement taken back: it left no fewer triangles turned over\n");
  if (r.folds_stopped_by_memory)
    summary("  folds      refining stopped: the next pass's cells would not fit the memory limit (raise --memory-limit)\n");
  if (s.exact_normals)
    summary("  normals    %llu representatives took the input's normal at their nearest input point\n",
                ull(s.exact_normals));
  if (s.normal_fallbacks) summary("  normals    %llu fell back (merged normals cancelled; the quadric's normal used)\n", ull(s.normal_fallbacks));
  summary("%s", quantisation.c_str());
  summary("  bytes      %llu (%s)\n", ull(bytes), format_bytes(bytes).c_str());
  summary("  time       open %.2f s, collapse %.2f s (%llu pages read, %llu inside one cell not; fold checks %.2f s, "
              "finish %.2f s), write %.2f s\n",
              open_seconds, r.seconds, ull(r.pages_read), ull(r.pages_skipped), r.fold_seconds, r.finish_seconds,
              write_seconds);
  summary("  memory     peak %s (mesh build %s, estimate %s)\n", format_bytes(peak_rss_bytes()).c_str(),
              format_bytes(s.peak_bytes).c_str(), format_bytes(estimate.bytes).c_str());
  return 0;
}

}  // namespace

RAYLOD_COMMAND("simplify", "collapse the probed cells and write the simplified mesh (.drc/.glb/.ply/.obj)", run_simplify);

}  // namespace raylod::cli
