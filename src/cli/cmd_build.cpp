// raylod build MESH [-o STORE] [--memory-limit SIZE] [--max-depth N] [--threads T] [--force] [--verify]
#include <cstdio>

#include "cli/cli.h"
#include "core/system.h"
#include "pipeline/pipeline.h"
#include "streaming/octree_store.h"

namespace raylod::cli {
namespace {

int run_build(int argc, char** argv) {
  Args args("build", "MESH [-o STORE] [--memory-limit SIZE] [--max-depth N] [--threads T]",
            "Streams MESH (.ply, .stl, .obj, .drc, .gltf, .glb) twice -- bounds, then binning -- into a\n"
            "disk-backed octree store: triangles in checksummed pages on disk, and per-node\n"
            "quadrics (Lindstrom, eq. 4 of the method) for levels 0..quadric_depth in a node\n"
            "table. quadric_depth is the deepest level <= --max-depth whose node table fits\n"
            "in half of what --memory-limit leaves after the reader and the batches in flight,\n"
            "stopping where cells hold about two vertices. Pages are the cells of one level\n"
            "chosen to hold about --page-triangles triangles each. Building again for an\n"
            "unchanged mesh (size, modification time, content hash) with the same options\n"
            "does nothing; a changed mesh is rebuilt, and so is a store in which a reader\n"
            "(run, probe, simplify) found a page whose checksum does not match (it records\n"
            "that in STORE.corrupt). The content hash is not read again while STORE.checked\n"
            "records the mesh's size, times and inode as they were when it last matched.\n"
            "--verify reads the mesh's content hash and checks every page's checksum of an\n"
            "up-to-date store, and rebuilds it if one does not match. The store is written\n"
            "atomically.",
            {{"--output", "-o", "store to write (default MESH.raylod beside the mesh)", true, "STORE"},
             {"--memory-limit", "", "memory bound for the build, e.g. 1G (default: a quarter of RAM)", true, "SIZE"},
             {"--max-depth", "", "deepest octree level that may keep quadrics, 0..21 (default 12)", true, "N"},
             threads_option("; the store does not depend on it"),
             {"--page-triangles", "", "target triangles per page (default 4096)", true, "N"},
             {"--force", "", "rebuild even if the store is up to date", false, ""},
             {"--verify", "", "hash the mesh and check every page's checksum of an up-to-date store; rebuild it on a mismatch", false, ""},
             quiet_option()});
  if (Status st = args.parse(argc, argv); !st) return fail("build", st);
  if (args.help_requested()) {
    std::printf("%s", args.help_text().c_str());
    return 0;
  }
  if (args.positionals().size() != 1) return fail("build", Status::error("expected one MESH (see raylod build --help)"));
  const std::filesystem::path mesh = args.positionals()[0];
  if (mesh.empty()) return fail("build", Status::error("the mesh: no file name given"));
  StoreOptions options;
  auto budget = memory_budget_from_args(args);
  if (!budget) return fail("build", budget.status());
  options.memory_limit = budget->total;
  auto depth = args.get_int("--max-depth", options.max_depth, 0, 21);
  if (!depth) return fail("build", depth.status());
  options.max_depth = int(*depth);
  auto page = args.get_int("--page-triangles", options.page_triangles, 1, 1 << 24);
  if (!page) return fail("build", page.status());
  options.page_triangles = uint32_t(*page);
  const bool quiet = apply_quiet(args);
  // Beside the mesh, or in the cache for a mesh in a read-only folder (as run finds it).
  std::string where;
  const std::filesystem::path store = args.has("--output") ? std::filesystem::path(args.get("--output"))
                                                           : store_path_for(mesh, default_cache_dir(), options, &where);
  if (Status st = check_outputs_apart({{store, "the store (-o)"}}, {{mesh, "the mesh"}}); !st) return fail("build", st);
  if (args.has("--output"))
    if (Status st = check_output_path(store, "the store (-o)"); !st) return fail("build", st);
  if (!where.empty() && !quiet) std::fprintf(stderr, "raylod build: %s\n", where.c_str());
  // --force replaces the old store atomically; it stays in place if the build fails.
  auto built = build_store(mesh, store, options, args.has("--force"), args.has("--verify"));
  if (!built) return fail("build", built.status());
  const BuildReport& r = *built;
  if (r.reused) {
    summary("%s: %s; nothing to do (use --force to rebuild)\n", store.string().c_str(), r.reason.c_str());
    return 0;
  }
  if (!r.warning.empty()) std::fprintf(stderr, "raylod build: warning: %s\n", r.warning.c_str());
  summary("built %s (%s)\n", store.string().c_str(), r.reason.c_str());
  summary("  triangles      %llu\n", (unsigned long long)r.triangles);
  summary("  levels         0..%d with quadrics%s, pages at level %d\n", r.quadric_depth,
              r.coarsened ? " (lowered during the build to fit --memory-limit)" : "", r.page_level);
  summary("  nodes          %llu (quadric memory %s)\n", (unsigned long long)r.nodes,
              format_bytes(r.node_table_bytes).c_str());
  summary("  pages          %llu (%.0f triangles per page on average)\n", (unsigned long long)r.pages,
              r.pages ? double(r.triangles) / double(r.pages) : 0.0);
  summary("  open edges     %llu (edges of one triangle: holes' and open surfaces' rims)%s\n",
              (unsigned long long)r.open_edges,
              r.open_edges_capped ? "; too many to match across pages within the memory limit, so some interior "
                                    "edges between pages were flagged too (more cells kept near them)"
                                  : "");
  summary("  store          %s (%.2fx the mesh's %s)\n", format_bytes(r.store_bytes).c_str(),
              r.source_bytes ? double(r.store_bytes) / double(r.source_bytes) : 0.0,
              format_bytes(r.source_bytes).c_str());
  summary("  time           %.2f s (%.2f M triangles/s): bounds %.2f, binning %.2f, pages %.2f, fsync %.2f\n",
              r.seconds, double(r.triangles) / r.seconds / 1e6, r.scan_seconds, r.bin_seconds, r.write_seconds,
              r.commit_seconds);
  summary("  peak RSS       %s (limit %s)\n", format_bytes(peak_rss_bytes()).c_str(),
              describe_memory_limit(options.memory_limit).c_str());
  return 0;
}

}  // namespace

RAYLOD_COMMAND("build", "stream a mesh into a disk-backed octree store with per-node quadrics", run_build);

}  // namespace raylod::cli
