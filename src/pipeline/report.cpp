#include "pipeline/report.h"

#include <chrono>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <sstream>
#include <thread>

#include <nlohmann/json.hpp>
#include <glm/gtc/matrix_transform.hpp>

#include "core/fault_point.h"
#include "core/system.h"
#include "gen/generate.h"
#include "pipeline/baselines.h"
#include "pipeline/plot.h"
#include "scene/scene_camera.h"
#include "render/embree_scene.h"
#include "simplify/collapse.h"

namespace raylod {
namespace fs = std::filesystem;

namespace {

std::string fmt(const char* f, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, f, v);
  return buf;
}

std::string slug(const std::string& s) {
  std::string out;
  for (char c : s) out += std::isalnum(static_cast<unsigned char>(c)) ? c : '-';
  return out;
}

// Colour of a collapse level for the cut picture (Figure 4(c)): coarse cells
// red, fine cells blue; cells not collapsed light grey.
Vec3 level_colour(int level, int lo, int hi) {
  static const Vec3 ramp[] = {{0.85f, 0.10f, 0.10f}, {0.95f, 0.55f, 0.10f}, {0.95f, 0.90f, 0.20f},
                              {0.30f, 0.75f, 0.30f}, {0.20f, 0.60f, 0.90f}, {0.35f, 0.25f, 0.80f}};
  double t = hi > lo ? double(level - lo) / double(hi - lo) : 0.0;
  double f = t * 5.0;
  int i = std::min(int(f), 4);
  return glm::mix(ramp[i], ramp[i + 1], float(f - i));
}

// Figure 4(c): the simplified mesh seen from the camera, coloured by the
// octree level of the collapsed cell each visible point lies in.
StatusOr<Image> cut_picture(const Scene& scene, const fs::path& simplified, const OctreeStore& store, const Cut& cut,
                            std::string* legend) {
  const Scene frame = in_render_frame(scene);
  const glm::dmat4 to_world = frame.objects[0].transform;
  RAYLOD_ASSIGN_OR_RETURN(TriangleMesh mesh, load_triangle_mesh(simplified, to_world, 0, scene.crease_angle_deg));
  std::vector<TriangleMesh> meshes;
  meshes.push_back(std::move(mesh));
  RAYLOD_ASSIGN_OR_RETURN(auto geometry, EmbreeScene::build(std::move(meshes)));
  std::vector<CellKey> keys;
  int lo = 64, hi = 0;
  for (const auto& c : cut.cells) {
    keys.push_back(c.key);
    lo = std::min(lo, int(c.key.level));
    hi = std::max(hi, int(c.key.level));
  }
  CutLookup lookup(store.header().root_lo, store.header().root_size, keys);
  // Store coordinates are relative to the mesh origin (the .drc's, composed in by the load).
  const glm::dmat4 to_object = glm::inverse(to_world * glm::translate(glm::dmat4(1.0), store.header().mesh_origin));
  PinholeCamera cam = make_pinhole_camera(frame.camera);
  Image img(scene.camera.width, scene.camera.height, 3);
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x) {
      Ray ray = cam.generate(x + 0.5, y + 0.5);
      Hit hit;
      Vec3 c(0.08f);
      if (geometry->intersect(ray, 0, 1e30, hit)) {
        Vec3d p = Vec3d(to_object * glm::dvec4(ray.at(hit.t), 1.0));
        uint32_t cell = lookup.find(p);
        c = cell == kKeepVertex ? Vec3(0.8f) : level_colour(int(keys[cell].level), lo, hi);
        // A little shading so the shape reads.
        const auto& m = geometry->mesh(hit.geom);
        const uint32_t* t = &m.indices[size_t(hit.prim) * 3];
        Vec3d n = face_normal(Vec3d(m.positions[t[0]]), Vec3d(m.positions[t[1]]), Vec3d(m.positions[t[2]]));
        c *= float(0.45 + 0.55 * std::abs(glm::dot(n, ray.direction)));
      }
      float* px = img.at(x, y);
      for (int k = 0; k < 3; ++k) px[k] = std::pow(c[k], 2.2f);  // write_image sRGB-encodes
    }
  if (legend) {
    *legend = "levels " + std::to_string(lo) + " (red, coarsest) to " + std::to_string(hi) +
              " (blue/violet, finest); grey: not collapsed";
  }
  return img;
}

struct SceneRun {
  std::string label;
  Scene scene;
};

std::string label_number(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", v);
  return buf;
}

// REPORT.md's first line starts with this: how an earlier report's folder,
// which a new report may replace, is told from a folder of other files.
constexpr const char* kReportTitle = "# raylod accuracy report";

// The list of every file a report wrote, one relative path a line (itself
// included), written last: what a later report may replace.
constexpr const char* kReportManifest = "report-files.txt";

// The files and folders under `dir` (relative paths; folders end in '/').
std::vector<std::string> entries_under(const fs::path& dir, std::error_code& ec) {
  std::vector<std::string> out;
  for (fs::recursive_directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    const fs::path rel = fs::relative(it->path(), dir, ec);
    const bool folder = it->is_directory(ec) && !it->is_symlink(ec);
    out.push_back(rel.string() + (folder ? "/" : ""));
  }
  std::sort(out.begin(), out.end());
  return out;
}

// Writes the manifest of the finished report in `dir`: every entry there.
Status write_report_manifest(const fs::path& dir) {
  std::error_code ec;
  std::vector<std::string> entries = entries_under(dir, ec);
  if (ec) return Status::error(dir.string() + ": cannot list the report's files: " + ec.message());
  entries.push_back(kReportManifest);
  std::sort(entries.begin(), entries.end());
  std::string text;
  for (const std::string& e : entries) text += e + "\n";
  return write_file_atomic(dir / kReportManifest, text);
}

// What the report's folder (-o) holds: nothing (missing or empty), an
// earlier report (REPORT.md with the report's title, and nothing but the
// files its manifest lists), or anything else: a file of the user's put
// in an earlier report (a note, the scene the report reads) keeps the
// folder from being replaced.
enum class FolderHolds { Nothing, Report, Other };
FolderHolds report_folder_holds(const fs::path& dir) {
  std::error_code ec;
  if (!fs::exists(dir, ec) && !ec) return FolderHolds::Nothing;
  const bool empty = fs::is_empty(dir, ec);
  if (ec) return FolderHolds::Other;  // unreadable: not replaced
  if (empty) return FolderHolds::Nothing;
  std::ifstream md(dir / "REPORT.md");
  std::string first;
  std::getline(md, first);
  if (first.rfind(kReportTitle, 0) != 0 || fs::is_symlink(dir / "REPORT.md", ec)) return FolderHolds::Other;
  std::ifstream manifest(dir / kReportManifest);
  std::vector<std::string> listed;
  for (std::string line; std::getline(manifest, line);) listed.push_back(line);
  std::sort(listed.begin(), listed.end());
  const std::vector<std::string> present = entries_under(dir, ec);
  if (ec || listed.empty()) return FolderHolds::Other;
  for (const std::string& e : present)
    if (!std::binary_search(listed.begin(), listed.end(), e)) return FolderHolds::Other;
  return FolderHolds::Report;
}

Status refuse_other_folder(const fs::path& out_dir) {
  return Status::error(out_dir.string() + ": the report folder (-o) holds files that are not a raylod report's (its " +
                       "REPORT.md and the files its " + kReportManifest + " lists); a report replaces its whole " +
                       "folder, so give a new or empty folder, or an earlier report's as it was written");
}

std::string mib(uint64_t bytes) { return fmt("%.1f", double(bytes) / (1024.0 * 1024.0)); }

// An image identical to the one it is compared with has an infinite PSNR,
// which JSON cannot hold: null, as in `run --compare`'s statistics, beside
// "identical": true (the full mesh's row, the reference itself, has null
// and no "identical").
nlohmann::json psnr_for_json(double psnr) { return std::isfinite(psnr) ? nlohmann::json(psnr) : nlohmann::json(nullptr); }

// A PSNR for the text: "51.93 dB", or "identical" for an image that equals
// the reference pixel for pixel.
std::string psnr_text(double psnr) { return std::isfinite(psnr) ? fmt("%.2f dB", psnr) : "identical"; }

nlohmann::json row_json(const ReportRow& r, const NoiseFloor* floor) {
  nlohmann::json j = {{"scene", r.scene}, {"method", r.method}, {"footprint_scale", r.footprint_scale}, {"rays", r.rays},
          {"triangles", r.triangles}, {"probe_seconds", r.probe_s}, {"simplify_seconds", r.simplify_s},
          {"render_seconds", r.render_s}, {"total_seconds", r.total_s}, {"drc_bytes", r.drc_bytes},
          {"memory_bytes", r.memory_bytes}, {"psnr", psnr_for_json(r.error.psnr)},
          {"ssim", r.error.ssim}, {"max_diff", r.error.max_diff}, {"image", r.image}, {"diff_image", r.diff_image}};
  if (r.method != "full mesh") j["identical"] = !std::isfinite(r.error.psnr);
  if (floor && r.method != "full mesh") j["within_noise_floor"] = within_noise_floor(r.error, *floor);
  return j;
}

// The table's PSNR cell: "reference" for the full mesh's row (the image the
// others are compared with), "identical" for another row whose image equals
// it exactly, else the PSNR in dB.
std::string psnr_cell(const ReportRow& r) {
  if (r.method == "full mesh") return "reference";
  return std::isfinite(r.error.psnr) ? fmt("%.2f", r.error.psnr) : "identical";
}

// A baseline's figures against raylod's default, for the text below a
// view's table: "PSNR 48.33 dB (raylod +4.16 dB)", or words for an image
// identical to the reference.
std::string against_baseline(const ReportRow& baseline, const ReportRow& raylod) {
  if (!std::isfinite(baseline.error.psnr)) return "an image identical to the reference";
  return "PSNR " + psnr_text(baseline.error.psnr) + " (raylod " +
         (std::isfinite(raylod.error.psnr) ? fmt("%+.2f dB", raylod.error.psnr - baseline.error.psnr)
                                           : std::string("identical")) +
         ")";
}

const NoiseFloor* find_floor(const std::vector<ReportView>& views, const std::string& scene) {
  for (const auto& v : views)
    if (v.scene == scene) return &v.noise_floor;
  return nullptr;
}

// The table's "vs noise floor" cell: how far a row's PSNR is below the
// view's floor, or that it is not.
std::string against_floor_cell(const ReportRow& r, const NoiseFloor* floor) {
  if (r.method == "full mesh") return "reference";
  if (!floor) return "";
  if (within_noise_floor(r.error, *floor)) return "indistinguishable";
  if (!std::isfinite(floor->psnr())) return "differs (floor: identical)";
  return fmt("%.2f dB below", floor->psnr() - r.error.psnr);
}

const ReportRow* find_row(const std::vector<ReportRow>& rows, const std::string& scene, const std::string& method,
                          uint64_t triangles_near = 0) {
  const ReportRow* best = nullptr;
  for (const auto& r : rows) {
    if (r.scene != scene || r.method != method) continue;
    if (!best) best = &r;
    else if (triangles_near &&
             std::llabs(int64_t(r.triangles) - int64_t(triangles_near)) <
                 std::llabs(int64_t(best->triangles) - int64_t(triangles_near)))
      best = &r;
  }
  return best;
}

// The paper's Table 1 (Miyashita et al., Sec. 5; METHOD.md): its glass bottle,
// uniformly tessellated, against the method, on their machine and renderer.
struct PaperTable1 {
  uint64_t triangles = 1053984, simplified = 44574, rays = 5000;
  double preprocessing_s = 60, full_render_s = 600, method_render_s = 420;
};

// True for the paper's scene: the generated bottle at the paper's count.
bool is_paper_bottle(const Scene& scene) {
  return scene.objects.size() == 1 && scene.objects[0].generate && scene.objects[0].generate->generator == "bottle" &&
         scene.objects[0].generate->triangles == PaperTable1{}.triangles;
}

// One view's figures in the layout of the paper's Table 1, with the paper's
// own figures beside them for its bottle scene.
void write_table1(std::ostringstream& md, const ReportRow& full, const ReportRow& def, const NoiseFloor* floor,
                  double build_seconds, bool paper) {
  const PaperTable1 p;
  md << "In the layout of the paper's Table 1";
  if (paper) md << " (the paper's columns are its own figures, on its machine and renderer)";
  md << ":\n\n| | full mesh | raylod (default) |" << (paper ? " paper: uniform | paper: method |" : "") << "\n";
  md << "|---|---:|---:|" << (paper ? "---:|---:|" : "") << "\n";
  md << "| triangles | " << full.triangles << " | " << def.triangles << " |"
     << (paper ? " " + std::to_string(p.triangles) + " | " + std::to_string(p.simplified) + " |" : "") << "\n";
  md << "| test rays | none | " << def.rays << " |" << (paper ? " none | " + std::to_string(p.rays) + " |" : "") << "\n";
  md << "| preprocessing s (probe + simplify) | none | " << fmt("%.2f", def.probe_s + def.simplify_s) << " |"
     << (paper ? " none | " + fmt("%.0f", p.preprocessing_s) + " |" : "") << "\n";
  md << "| rendering s (load, BVH, trace) | " << fmt("%.2f", full.render_s) << " | " << fmt("%.2f", def.render_s) << " |"
     << (paper ? " " + fmt("%.0f", p.full_render_s) + " | " + fmt("%.0f", p.method_render_s) + " |" : "") << "\n";
  md << "| PSNR against the full mesh | reference | " << psnr_text(def.error.psnr)
     << (floor ? " (noise floor " + fmt("%.2f dB", floor->psnr()) + ")" : std::string()) << " |"
     << (paper ? " reference | not reported |" : "") << "\n\n";
  md << "The store is built once per mesh and reused by every view (" << fmt("%.2f s", build_seconds)
     << " in this report, about 0 if it was already current).\n\n";
}

Status write_report_files(const fs::path& out_dir, const ReportResult& result, const ReportConfig& cfg,
                          const SceneStores& stores, double load_seconds,
                          const std::map<std::string, std::string>& cut_legends, const Scene& input_scene) {
  // Machine-readable data first.
  nlohmann::json j;
  j["mesh"] = stores.meshes[0].string();
  j["triangles"] = stores.triangles;
  j["default_footprint_scale"] = cfg.default_scale;
  j["default_rays"] = cfg.default_rays;
  j["baseline_load_seconds"] = load_seconds;
  j["rows"] = nlohmann::json::array();
  for (const auto& r : result.rows) j["rows"].push_back(row_json(r, find_floor(result.views, r.scene)));
  j["noise_floors"] = nlohmann::json::array();
  for (const auto& v : result.views) {
    const NoiseFloor& f = v.noise_floor;
    j["noise_floors"].push_back({{"scene", v.scene}, {"seed", f.seed}, {"other_seed", noise_floor_seed(f.seed)},
                                 {"spp", f.spp}, {"psnr", psnr_for_json(f.psnr())},
                                 {"identical", !std::isfinite(f.psnr())}, {"ssim", f.error.ssim},
                                 {"max_diff", f.error.max_diff}, {"render_seconds", f.render_seconds}});
  }
  RAYLOD_RETURN_IF_ERROR(write_file_atomic(out_dir / "report.json", j.dump(2) + "\n"));

  std::ostringstream md;
  md << kReportTitle << ": what accuracy costs in time\n\n";
  md << "Mesh `" << stores.meshes[0].filename().string() << "`, " << stores.triangles << " triangles. ";
  md << "Error is measured against the render of the full-resolution mesh (PSNR and SSIM on the displayed, "
        "sRGB-encoded image; largest absolute channel difference in [0, 1]). Times are wall-clock seconds on this "
        "machine (" << std::thread::hardware_concurrency() << " hardware threads, "
     << format_bytes(physical_memory_bytes()) << "). raylod's total is probe + simplify + render (render = load the "
        ".drc + BVH build + trace); a baseline's total is loading the full mesh (" << fmt("%.2f s", load_seconds)
     << ") + simplifying it in memory + BVH build + trace. Memory: for the full mesh and raylod, the mesh and BVH "
        "the renderer holds; for the baselines, the loaded mesh plus the simplifier's peak allocations.\n\n";
  md << "raylod collapses a cell when the surface deviation the collapse causes (its quadric's chord error) stays "
        "under " << label_number(kDefaultTolerancePx) << " pixel of the footprint of the rays that see it, and its "
        "diagonal under K footprints (the deviation criterion; the default K = " << label_number(cfg.default_scale)
     << ", " << cfg.default_rays << " test rays). Rows \"raylod (diagonal)\" use the paper's test alone "
        "(diagonal < K footprints) for comparison. The rays are traced once per ray count and every K selects its cut "
        "from that trace; a row's probe time is the trace plus its own selection.\n\n";
  md << "Each view's noise floor is the error of the full mesh rendered at the next seed (same samples per pixel) "
        "against the reference: the difference sampling alone makes. A row whose PSNR is at or above the floor is "
        "\"indistinguishable\" from the full mesh at this sample count; otherwise the table says how many dB below "
        "the floor it is.\n\n";

  std::vector<std::string> scenes;
  for (const auto& r : result.rows)
    if (std::find(scenes.begin(), scenes.end(), r.scene) == scenes.end()) scenes.push_back(r.scene);

  for (const auto& scene : scenes) {
    const std::string tag = slug(scene);
    const NoiseFloor* floor = find_floor(result.views, scene);
    md << "## " << scene << " view\n\n";
    if (floor) {
      md << "Noise floor: PSNR " << (std::isfinite(floor->psnr()) ? fmt("%.2f dB", floor->psnr()) : "infinite")
         << ", SSIM " << fmt("%.4f", floor->error.ssim) << ", max diff " << fmt("%.3f", floor->error.max_diff)
         << " (full mesh at seed " << noise_floor_seed(floor->seed) << " against the reference at seed " << floor->seed
         << ", " << floor->spp << " spp).\n\n";
    }
    md << "| method | K | test rays | triangles | probe s | simplify s | render s | total s | .drc MiB | memory MiB "
          "| PSNR dB | SSIM | max diff | vs noise floor |\n";
    md << "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|\n";
    for (const auto& r : result.rows) {
      if (r.scene != scene) continue;
      const bool ray = r.method.rfind("raylod", 0) == 0;
      md << "| " << r.method << " | " << (ray ? label_number(r.footprint_scale) : "") << " | "
         << (ray ? std::to_string(r.rays) : "") << " | " << r.triangles << " | " << (ray ? fmt("%.2f", r.probe_s) : "")
         << " | " << (r.method == "full mesh" ? "" : fmt("%.2f", r.simplify_s)) << " | " << fmt("%.2f", r.render_s)
         << " | " << fmt("%.2f", r.total_s) << " | " << (ray ? mib(r.drc_bytes) : "") << " | " << mib(r.memory_bytes)
         << " | " << psnr_cell(r) << " | "
         << fmt("%.4f", r.error.ssim) << " | " << fmt("%.3f", r.error.max_diff) << " | "
         << against_floor_cell(r, floor) << " |\n";
    }
    md << "\n";

    // The figures the method is judged by, at the default settings.
    const ReportRow* full = find_row(result.rows, scene, "full mesh");
    const ReportRow* def = nullptr;
    for (const auto& r : result.rows)
      if (r.scene == scene && r.method == "raylod" && r.footprint_scale == cfg.default_scale &&
          r.rays == cfg.default_rays)
        def = &r;
    if (def && full) {
      const ReportRow* vc = find_row(result.rows, scene, "vertex clustering", def->triangles);
      const ReportRow* ec = find_row(result.rows, scene, "edge collapse", def->triangles);
      md << "At the default settings: " << fmt("%.1f", double(full->triangles) / std::max<uint64_t>(def->triangles, 1))
         << "x fewer triangles than the input, "
         << (std::isfinite(def->error.psnr) ? "PSNR " + psnr_text(def->error.psnr) : "an image identical to the reference")
         << (floor ? " (" + describe_against_noise_floor(def->error, *floor) + ")" : std::string()) << "; probe + simplify + "
         << "render " << fmt("%.2f s", def->total_s) << " against " << fmt("%.2f s", full->total_s)
         << " to render the full mesh (load and BVH included).";
      if (vc)
        md << " Uniform vertex clustering at " << vc->triangles << " triangles: " << against_baseline(*vc, *def) << ".";
      if (ec)
        md << " Quadric edge collapse at " << ec->triangles << " triangles: " << against_baseline(*ec, *def) << ".";
      md << "\n\n";
      write_table1(md, *full, *def, floor, stores.seconds, is_paper_bottle(input_scene));
      md << "| reference (full mesh) | raylod (default) | difference x4 | cut: collapse level |\n|---|---|---|---|\n";
      md << "| ![](" << full->image << ") | ![](" << def->image << ") | ![](" << def->diff_image << ") | ![]("
         << tag << "-cut.png) |\n\n";
      auto legend = cut_legends.find(scene);
      if (legend != cut_legends.end()) md << "Cut picture: " << legend->second << ".\n\n";
      md << "Wireframe of raylod's simplified mesh (triangle density): ![](" << tag << "-raylod-wireframe.png)\n\n";
      if (vc && ec) {
        md << "Baselines at the same triangle count (difference x4):\n\n| vertex clustering | edge collapse |\n"
              "|---|---|\n| ![](" << vc->diff_image << ") | ![](" << ec->diff_image << ") |\n\n";
      }
    }

    // Accuracy against time, one curve per method.
    std::vector<PlotSeries> series;
    PlotSeries k_sweep{"raylod, K sweep (" + std::to_string(cfg.default_rays) + " rays)", {0.85f, 0.15f, 0.1f}, {}};
    PlotSeries ray_sweep{"raylod, test-ray sweep (K = " + label_number(cfg.default_scale) + ")", {0.95f, 0.6f, 0.1f}, {}};
    PlotSeries vc{"vertex clustering (meshopt sloppy)", {0.2f, 0.45f, 0.85f}, {}};
    PlotSeries ec{"quadric edge collapse (meshopt)", {0.2f, 0.65f, 0.3f}, {}};
    for (const auto& r : result.rows) {
      if (r.scene != scene || !std::isfinite(r.error.psnr)) continue;
      std::pair<double, double> pt{r.total_s, r.error.psnr};
      if (r.method == "raylod" && r.rays == cfg.default_rays) k_sweep.points.push_back(pt);
      if (r.method == "raylod" && r.footprint_scale == cfg.default_scale) ray_sweep.points.push_back(pt);
      if (r.method == "vertex clustering") vc.points.push_back(pt);
      if (r.method == "edge collapse") ec.points.push_back(pt);
    }
    auto by_x = [](PlotSeries& s) { std::sort(s.points.begin(), s.points.end()); };
    by_x(k_sweep); by_x(ray_sweep); by_x(vc); by_x(ec);
    for (auto* s : {&k_sweep, &ray_sweep, &vc, &ec})
      if (!s->points.empty()) series.push_back(*s);
    // The noise floor as a horizontal line across the measured times.
    if (!series.empty() && floor && std::isfinite(floor->psnr())) {
      double x0 = INFINITY, x1 = -INFINITY;
      for (const auto& s : series)
        for (const auto& p : s.points) { x0 = std::min(x0, p.first); x1 = std::max(x1, p.first); }
      series.push_back({"noise floor (full mesh, next seed)", {0.45f, 0.45f, 0.45f},
                        {{x0, floor->psnr()}, {x1, floor->psnr()}}});
    }
    if (!series.empty()) {
      PlotConfig pc;
      pc.title = scene + " view: image error against time (full mesh: " + fmt("%.1f s", full ? full->total_s : 0) + ")";
      pc.x_label = "total time [s]";
      pc.y_label = "PSNR [dB]";
      const std::string plot = tag + "-accuracy-vs-time.png";
      RAYLOD_RETURN_IF_ERROR(write_plot(out_dir / plot, series, pc));
      md << "Accuracy against time (higher and further left is better):\n\n![](" << plot << ")\n\n";
    }
  }
  md << "Data: `report.json`. Regenerate with the command in README.md (\"What accuracy costs\").\n";
  RAYLOD_RETURN_IF_ERROR(write_file_atomic(out_dir / "REPORT.md", md.str()));
  return {};
}

}  // namespace

Scene closeup_scene(const Scene& scene) {
  Scene s = scene;
  s.camera.eye = s.camera.look_at + (s.camera.eye - s.camera.look_at) * 0.25;
  s.camera.fov_y_deg = std::max(10.0, s.camera.fov_y_deg * 0.8);
  return s;
}

StatusOr<ReportResult> run_report(const Scene& input_scene, const std::optional<fs::path>& mesh_override,
                                  const ReportConfig& cfg, const LogFn& log) {
  auto say = [&](const std::string& m) { if (log) log(m); };
  if (input_scene.objects.size() != 1)
    return Status::error("the report compares simplifiers on one mesh; the scene has " +
                         std::to_string(input_scene.objects.size()) + " objects");
  // The report's folder is made if missing, but not the folders above it:
  // a typo there is an error, as for every command's outputs. The report is
  // written into a temporary folder beside it (AtomicDirectory), which takes
  // its place only once complete: an earlier report there is replaced whole
  // (none of its files stay), and a failure or an interruption leaves it as
  // it was. A folder that holds anything but an earlier report is refused
  // before any work: the report never removes other files.
  fs::path dir = cfg.out_dir.lexically_normal();
  if (dir.empty()) return Status::error("--output: no folder name given");
  if (!dir.has_filename()) dir = dir.parent_path();  // "out/"
  std::error_code ec;
  if (fs::exists(dir, ec) && !fs::is_directory(dir, ec))
    return Status::error(cfg.out_dir.string() + ": the report folder (-o) names a file, not a directory");
  const fs::path parent = dir.has_parent_path() ? dir.parent_path() : fs::path(".");
  if (!fs::is_directory(parent, ec))
    return Status::error(cfg.out_dir.string() + ": the report folder (-o): directory " + parent.string() +
                         " does not exist");
  // The folder is replaced whole, so never the one the shell stands in or
  // one above it ("-o ." would leave the shell in a removed folder).
  {
    const fs::path here = fs::weakly_canonical(fs::current_path(ec), ec);
    const fs::path target = fs::weakly_canonical(fs::absolute(dir, ec), ec);
    if (!ec && !target.empty()) {
      const auto [t, h] = std::mismatch(target.begin(), target.end(), here.begin(), here.end());
      if (t == target.end())
        return Status::error(cfg.out_dir.string() +
                             ": the report folder (-o) is the current folder or holds it; the report replaces its "
                             "folder whole: name another, such as a subfolder");
    }
  }
  if (report_folder_holds(dir) == FolderHolds::Other) return refuse_other_folder(cfg.out_dir);
  AtomicDirectory staged(dir);
  RAYLOD_RETURN_IF_ERROR(staged.create());
  const fs::path out_dir = staged.temp_path();  // every file goes here
  const fs::path cache_dir = cfg.cache_dir.empty() ? default_cache_dir() : cfg.cache_dir;

  Scene base = input_scene;
  if (cfg.width > 0) base.camera.width = cfg.width;
  if (cfg.height > 0) base.camera.height = cfg.height;
  const MemoryBudget budget = MemoryBudget::of(cfg.memory_limit);
  StoreOptions store_options;
  store_options.memory_limit = budget.total;
  const uint64_t memory_limit = budget.working();
  RAYLOD_ASSIGN_OR_RETURN(SceneStores stores, prepare_scene_stores(base, mesh_override, store_options, cache_dir, log));
  const OctreeStore& store = *stores.stores[0];
  const fs::path mesh_path = stores.meshes[0];

  std::vector<SceneRun> runs{{"default", base}};
  if (cfg.closeup) runs.push_back({"close-up", closeup_scene(base)});

  RenderOptions ro;
  ro.spp = cfg.spp;
  ro.memory_limit = memory_limit;
  ro.progress = cfg.progress;

  // The baselines simplify the fully loaded mesh: load it once, in world
  // space (the render frame's, as render_embree_scene traces it).
  std::optional<TriangleMesh> loaded;
  double load_seconds = 0;
  if (cfg.baselines) {
    auto t0 = std::chrono::steady_clock::now();
    RAYLOD_ASSIGN_OR_RETURN(TriangleMesh m, load_triangle_mesh(mesh_path, in_render_frame(base).objects[0].transform,
                                                              base.objects[0].material, base.crease_angle_deg));
    load_seconds = seconds_since(t0);
    loaded = std::move(m);
    say("loaded " + std::to_string(loaded->triangle_count()) + " triangles for the baselines in " +
        fmt("%.2f s", load_seconds));
  }

  ReportResult result;
  std::map<std::string, std::string> cut_legends;
  const fs::path scratch = out_dir / "meshes";
  fs::create_directories(scratch, ec);

  for (const auto& run : runs) {
    const std::string tag = slug(run.label);
    // Reference: the full-resolution mesh, rendered the same way.
    RAYLOD_ASSIGN_OR_RETURN(FullRender full, render_full_with_noise_floor(run.scene, ro));
    const RenderResult& reference = full.reference;
    result.views.push_back({run.label, full.noise_floor});
    const RenderStats& rs = reference.stats;
    ReportRow ref;
    ref.scene = run.label;
    ref.method = "full mesh";
    ref.triangles = stores.triangles;
    ref.render_s = rs.load_seconds + rs.bvh_seconds + rs.render_seconds;
    ref.total_s = ref.render_s;
    ref.memory_bytes = rs.mesh_bytes + rs.bvh_bytes;
    ref.error.psnr = INFINITY;
    ref.error.ssim = 1;
    ref.image = tag + "-reference.png";
    RAYLOD_RETURN_IF_ERROR(write_image(out_dir / ref.image, reference.color));
    result.rows.push_back(ref);
    say(run.label + ": reference render " + fmt("%.2f s", ref.render_s) + "; noise floor (seed " +
        std::to_string(noise_floor_seed(full.noise_floor.seed)) + " against " + std::to_string(full.noise_floor.seed) +
        ") PSNR " + fmt("%.2f dB", full.noise_floor.psnr()) + ", SSIM " + fmt("%.4f", full.noise_floor.error.ssim));

    // raylod: the K sweep at the default ray count (deviation criterion, then
    // the paper's diagonal test), then the ray sweep at the default K. Rays
    // are traced once per ray count; each variant selects its cut from that
    // trace, and its probe time is the trace plus its own selection.
    struct Variant { double k; uint64_t rays; CutCriterion criterion; };
    std::vector<Variant> variants;
    for (double k : cfg.footprint_scales) variants.push_back({k, cfg.default_rays, CutCriterion::Deviation});
    for (double k : cfg.diagonal_scales) variants.push_back({k, cfg.default_rays, CutCriterion::Diagonal});
    for (uint64_t n : cfg.ray_counts)
      if (n != cfg.default_rays) variants.push_back({cfg.default_scale, n, CutCriterion::Deviation});
    std::map<uint64_t, ProbeTrace> traces;
    std::vector<uint64_t> targets;
    for (const Variant& variant : variants) {
      const double k = variant.k;
      const uint64_t n = variant.rays;
      const bool diagonal = variant.criterion == CutCriterion::Diagonal;
      ReportRow row;
      row.scene = run.label;
      row.method = diagonal ? "raylod (diagonal)" : "raylod";
      row.footprint_scale = k;
      row.rays = n;
      RAYLOD_ASSIGN_OR_RETURN(ProbeConfig pc, make_probe_config(run.scene, n, k, budget, false));
      pc.criterion = variant.criterion;
      const int spp = cfg.spp > 0 ? cfg.spp : run.scene.spp;  // as the images are rendered
      pc.tolerance_px = default_tolerance_px(spp);
      pc.angle_tolerance_px = default_angle_tolerance_px(spp);
      if (!traces.count(n)) {
        RAYLOD_ASSIGN_OR_RETURN(ProbeTrace t, trace_probe(run.scene, stores.probe_stores, stores.objects, pc));
        traces.emplace(n, std::move(t));
      }
      const ProbeTrace& trace = traces.at(n);
      auto t0 = std::chrono::steady_clock::now();
      RAYLOD_ASSIGN_OR_RETURN(ProbeResult probe, select_cuts(trace, run.scene, stores.probe_stores, stores.objects, pc));
      row.probe_s = trace.trace_seconds + seconds_since(t0);
      const std::string name =
          tag + (diagonal ? "-raylod-diagonal-K" : "-raylod-K") + label_number(k) + "-rays" + std::to_string(n);
      fs::path drc = scratch / (name + ".drc");
      RAYLOD_ASSIGN_OR_RETURN(SimplifiedMesh sm,
                              simplify_cut_to_draco(store, probe.cuts[0], drc, memory_limit,
                                                    shading_normal_tolerance(run.scene), false, &row.simplify_s,
                                                    run.scene.crease_angle_deg,
                                                    fold_passes_for(run.scene, stores.objects, 0)));
      row.triangles = sm.triangles;
      row.drc_bytes = sm.drc_bytes;
      RenderOptions o = ro;
      o.mesh_override = {drc};
      RAYLOD_ASSIGN_OR_RETURN(RenderResult img, render(run.scene, o));
      row.render_s = img.stats.load_seconds + img.stats.bvh_seconds + img.stats.render_seconds;
      row.total_s = row.probe_s + row.simplify_s + row.render_s;
      row.memory_bytes = img.stats.mesh_bytes + img.stats.bvh_bytes;
      RAYLOD_ASSIGN_OR_RETURN(row.error, compare_images(img.color, reference.color));
      const bool is_default = !diagonal && k == cfg.default_scale && n == cfg.default_rays;
      if (is_default || n == cfg.default_rays) {
        row.image = name + ".png";
        row.diff_image = name + ".diff.png";
        RAYLOD_RETURN_IF_ERROR(write_image(out_dir / row.image, img.color));
        RAYLOD_RETURN_IF_ERROR(write_image(out_dir / row.diff_image, difference_image(img.color, reference.color)));
      }
      if (is_default) {
        std::string legend;
        RAYLOD_ASSIGN_OR_RETURN(Image cut_img, cut_picture(run.scene, drc, store, probe.cuts[0], &legend));
        RAYLOD_RETURN_IF_ERROR(write_image(out_dir / (tag + "-cut.png"), cut_img));
        cut_legends[run.label] = legend;
        RenderOptions w = o;
        w.wireframe = true;
        RAYLOD_ASSIGN_OR_RETURN(RenderResult wire, render(run.scene, w));
        RAYLOD_RETURN_IF_ERROR(write_image(out_dir / (tag + "-raylod-wireframe.png"), wire.color));
      }
      if (n == cfg.default_rays && !diagonal) targets.push_back(row.triangles);
      say(run.label + ": " + row.method + " K=" + label_number(k) + " rays=" + std::to_string(n) + ": " +
          std::to_string(row.triangles) + " triangles, PSNR " + psnr_text(row.error.psnr) + " (" +
          describe_against_noise_floor(row.error, full.noise_floor) + "), total " + fmt("%.2f s", row.total_s));
      result.rows.push_back(row);
    }

    // Baselines at the same triangle counts as the K sweep.
    if (loaded) {
      for (Baseline method : {Baseline::VertexClustering, Baseline::EdgeCollapse}) {
        for (uint64_t target : targets) {
          BaselineResult b = run_baseline(method, *loaded, target);
          ReportRow row;
          row.scene = run.label;
          row.method = method == Baseline::VertexClustering ? "vertex clustering" : "edge collapse";
          row.triangles = b.mesh.triangle_count();
          row.simplify_s = b.seconds;
          row.memory_bytes = b.peak_bytes;
          std::vector<TriangleMesh> meshes;
          meshes.push_back(std::move(b.mesh));
          if (run.scene.ground) {
            const Scene frame = in_render_frame(run.scene);
            meshes.push_back(make_ground_mesh(*frame.ground, frame.camera));
          }
          auto t0 = std::chrono::steady_clock::now();
          RAYLOD_ASSIGN_OR_RETURN(auto geometry, EmbreeScene::build(std::move(meshes)));
          RenderResult img = render_embree_scene(*geometry, run.scene, ro);
          row.render_s = seconds_since(t0);
          // Load of the full mesh + simplification + BVH and trace.
          row.total_s = load_seconds + row.simplify_s + row.render_s;
          RAYLOD_ASSIGN_OR_RETURN(row.error, compare_images(img.color, reference.color));
          const std::string name = tag + "-" + slug(row.method) + "-" + std::to_string(row.triangles);
          row.image = name + ".png";
          row.diff_image = name + ".diff.png";
          RAYLOD_RETURN_IF_ERROR(write_image(out_dir / row.image, img.color));
          RAYLOD_RETURN_IF_ERROR(write_image(out_dir / row.diff_image, difference_image(img.color, reference.color)));
          say(run.label + ": " + row.method + " " + std::to_string(row.triangles) + " triangles, PSNR " +
              psnr_text(row.error.psnr) + " (" + describe_against_noise_floor(row.error, full.noise_floor) + ")");
          result.rows.push_back(row);
        }
      }
    }
  }

  // A fault point (core/fault_point.h): the pictures written, the tables not.
  if (fault_point("report.files"))
    return Status::error(out_dir.string() + ": cannot write the tables: failed at fault point report.files");
  RAYLOD_RETURN_IF_ERROR(write_report_files(out_dir, result, cfg, stores, load_seconds, cut_legends, input_scene));
  RAYLOD_RETURN_IF_ERROR(write_report_manifest(out_dir));
  // Whatever came into the folder while the report ran is not replaced either.
  if (report_folder_holds(staged.target()) == FolderHolds::Other) return refuse_other_folder(cfg.out_dir);
  RAYLOD_RETURN_IF_ERROR(staged.commit());
  if (!staged.leftover().empty()) result.warnings.push_back(staged.leftover());
  result.markdown = cfg.out_dir / "REPORT.md";
  result.plot = cfg.out_dir / "default-accuracy-vs-time.png";
  return result;
}

}  // namespace raylod
