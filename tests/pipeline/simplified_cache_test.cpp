// The simplified-mesh cache: the reuse rule on tiny cuts, verification of
// entries, eviction, and what a killed run can leave behind.
#include <gtest/gtest.h>

#include <unistd.h>

#include <filesystem>
#include <fstream>

#include "pipeline/simplified_cache.h"
#include "test_tmp.h"

namespace raylod {
namespace {

namespace fs = std::filesystem;

fs::path fresh_dir(const std::string& name) {
  fs::path d = test::scratch_dir("cache-test") / name;
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

Cut make_cut(uint64_t store_hash, std::vector<CellKey> cells) {
  Cut cut;
  cut.store_hash = store_hash;
  for (auto k : cells) cut.cells.push_back(CollapsedCell{k, 0.01f, 1});
  std::sort(cut.cells.begin(), cut.cells.end(), [](const auto& a, const auto& b) { return a.key < b.key; });
  return cut;
}

fs::path write_file(const fs::path& p, size_t bytes, char fill) {
  std::ofstream(p, std::ios::binary) << std::string(bytes, fill);
  return p;
}

TEST(ReuseRule, SameCutIsFineEnough) {
  Cut a = make_cut(7, {{3, 5}, {4, 100}});
  EXPECT_TRUE(cut_is_at_least_as_fine(a, a));
}

TEST(ReuseRule, FinerCachedCellsAreFineEnough) {
  // Cached collapsed a child of the cell the new view collapses: finer. OK.
  Cut cached = make_cut(7, {{4, (5u << 3) | 2}});
  Cut wanted = make_cut(7, {{3, 5}});
  EXPECT_TRUE(cut_is_at_least_as_fine(cached, wanted));
}

TEST(ReuseRule, CoarserCachedCellIsRejectedWithReason) {
  Cut cached = make_cut(7, {{3, 5}});
  Cut wanted = make_cut(7, {{4, (5u << 3) | 2}});
  std::string why;
  EXPECT_FALSE(cut_is_at_least_as_fine(cached, wanted, &why));
  EXPECT_NE(why.find("level 3"), std::string::npos) << why;
}

TEST(ReuseRule, CellTheNewViewKeepsIsRejected) {
  Cut cached = make_cut(7, {{3, 5}, {3, 6}});
  Cut wanted = make_cut(7, {{3, 5}});
  EXPECT_FALSE(cut_is_at_least_as_fine(cached, wanted));
  // An uncollapsed cached mesh (empty cut) is fine for any view.
  EXPECT_TRUE(cut_is_at_least_as_fine(make_cut(7, {}), wanted));
}

TEST(ReuseRule, OtherStoreIsRejected) {
  EXPECT_FALSE(cut_is_at_least_as_fine(make_cut(7, {}), make_cut(8, {})));
}

TEST(SimplifiedCache, InsertThenExactHit) {
  fs::path dir = fresh_dir("exact");
  auto cache = SimplifiedCache::open(dir, 1 << 20);
  ASSERT_TRUE(cache.is_ok()) << cache.status().message();
  Cut cut = make_cut(42, {{2, 1}});
  fs::path drc = write_file(dir / "staged.drc", 1000, 'a');
  auto entry = cache->insert(cut, drc, 123, 0.001);
  ASSERT_TRUE(entry.is_ok()) << entry.status().message();
  auto hit = cache->find_exact(SimplifiedCache::key_for(cut));
  ASSERT_TRUE(hit.has_value());
  EXPECT_EQ(hit->triangles, 123u);
  EXPECT_TRUE(fs::exists(hit->mesh));
}

TEST(SimplifiedCache, FailedInsertLeavesNoPartialEntry) {
  // The copy of the mesh into the cache fails after the cut was written (as
  // on a full disk): the insert reports it and removes what it wrote.
  fs::path dir = fresh_dir("failed-insert");
  auto cache = SimplifiedCache::open(dir, 1 << 20);
  ASSERT_TRUE(cache.is_ok());
  Cut cut = make_cut(42, {{2, 1}});
  const std::string key = SimplifiedCache::key_for(cut);
  const fs::path blocker = dir / "simplified" / (key + ".drc.tmp-insert");
  fs::create_directories(blocker / "in-the-way");
  auto entry = cache->insert(cut, write_file(dir / "staged.drc", 1000, 'a'), 5, 0.001);
  ASSERT_FALSE(entry.is_ok());
  EXPECT_NE(entry.status().message().find(key), std::string::npos) << entry.status().message();
  for (const char* ext : {".cut", ".json", ".drc"}) EXPECT_FALSE(fs::exists(dir / "simplified" / (key + ext))) << ext;
  EXPECT_FALSE(cache->find_exact(key).has_value());
  // Once the disk has room again (the obstacle gone), the same insert works.
  fs::remove_all(blocker);
  EXPECT_TRUE(cache->insert(cut, dir / "staged.drc", 5, 0.001).is_ok());
  EXPECT_TRUE(cache->find_exact(key).has_value());
}

TEST(SimplifiedCache, CorruptEntryIsRemovedNotReturned) {
  fs::path dir = fresh_dir("corrupt");
  auto cache = SimplifiedCache::open(dir, 1 << 20);
  ASSERT_TRUE(cache.is_ok());
  Cut cut = make_cut(42, {{2, 1}});
  auto entry = cache->insert(cut, write_file(dir / "staged.drc", 1000, 'a'), 5, 0.001);
  ASSERT_TRUE(entry.is_ok());
  write_file(entry->mesh, 1000, 'b');  // same size, other content
  std::string note;
  EXPECT_FALSE(cache->find_exact(entry->key, &note).has_value());
  EXPECT_NE(note.find("corrupt"), std::string::npos) << note;
  EXPECT_FALSE(fs::exists(entry->mesh));
  EXPECT_FALSE(cache->find_reusable(cut, 1.0).has_value());
}

TEST(SimplifiedCache, AnEntryWhoseCutIsNotTheOneItWasMadeFromIsRemovedNotReused) {
  // A coarse mesh whose .cut was replaced by a fine cut's (copied over by
  // hand, or another entry's): the reuse rule would read the fine cut and
  // hand out the coarse mesh. The key hashes the cut the mesh was made from.
  fs::path dir = fresh_dir("swapped");
  auto cache = SimplifiedCache::open(dir, 1 << 20);
  ASSERT_TRUE(cache.is_ok());
  Cut fine = make_cut(9, {{4, 40}});
  Cut coarse = make_cut(9, {{2, 0}});
  auto f = cache->insert(fine, write_file(dir / "a.drc", 100, 'a'), 500, 0.001);
  auto c = cache->insert(coarse, write_file(dir / "c.drc", 100, 'c'), 100, 0.001);
  ASSERT_TRUE(f.is_ok() && c.is_ok());
  Cut wanted = make_cut(9, {{3, 5}});
  ASSERT_EQ(cache->find_reusable(wanted, 1.0)->key, f->key);  // the coarse one is too coarse
  fs::copy_file(f->cut, c->cut, fs::copy_options::overwrite_existing);
  auto got = cache->find_reusable(wanted, 1.0);
  ASSERT_TRUE(got.has_value());
  EXPECT_EQ(got->key, f->key);
  EXPECT_EQ(got->triangles, 500u);
  EXPECT_FALSE(fs::exists(c->mesh));
  EXPECT_FALSE(fs::exists(c->cut));
}

TEST(SimplifiedCache, ReusesTheCoarsestFineEnoughEntry) {
  fs::path dir = fresh_dir("reuse");
  auto cache = SimplifiedCache::open(dir, 1 << 20);
  ASSERT_TRUE(cache.is_ok());
  Cut fine = make_cut(9, {{4, 40}});
  Cut finer = make_cut(9, {});
  Cut coarse = make_cut(9, {{2, 0}});
  ASSERT_TRUE(cache->insert(fine, write_file(dir / "a.drc", 100, 'a'), 500, 0.001).is_ok());
  ASSERT_TRUE(cache->insert(finer, write_file(dir / "b.drc", 100, 'b'), 900, 0.001).is_ok());
  ASSERT_TRUE(cache->insert(coarse, write_file(dir / "c.drc", 100, 'c'), 100, 0.001).is_ok());
  // The new view collapses level-3 cell 5 (which contains level-4 cell 40):
  // "fine" and "finer" qualify, "coarse" (level 2, cell 0) is too coarse.
  Cut wanted = make_cut(9, {{3, 5}});
  std::string why;
  auto got = cache->find_reusable(wanted, 1.0, &why);
  ASSERT_TRUE(got.has_value());
  EXPECT_EQ(got->triangles, 500u) << why;
  EXPECT_FALSE(why.empty());
}

TEST(SimplifiedCache, CoarserQuantisationIsNotReused) {
  fs::path dir = fresh_dir("quantisation");
  auto cache = SimplifiedCache::open(dir, 1 << 20);
  ASSERT_TRUE(cache.is_ok());
  Cut cut = make_cut(9, {{3, 5}});
  ASSERT_TRUE(cache->insert(cut, write_file(dir / "a.drc", 100, 'a'), 50, 0.01).is_ok());
  EXPECT_TRUE(cache->find_reusable(cut, 0.01).has_value());
  EXPECT_FALSE(cache->find_reusable(cut, 0.001).has_value());
}

// A mesh simplified with exact normals (mirror and glass meshes with
// normals) differs from one simplified without at the same cut: neither is
// found for the other, and entries from before exact normals (no such field
// in their metadata) count as made without.
TEST(SimplifiedCache, ExactNormalsAreAnotherNormalRule) {
  fs::path dir = fresh_dir("exact-normals");
  auto cache = SimplifiedCache::open(dir, 1 << 20);
  ASSERT_TRUE(cache.is_ok());
  Cut cut = make_cut(9, {{3, 5}});
  EXPECT_NE(SimplifiedCache::key_for(cut, 30, true), SimplifiedCache::key_for(cut, 30, false));
  ASSERT_TRUE(cache->insert(cut, write_file(dir / "a.drc", 100, 'a'), 50, 0.01, 30, false).is_ok());
  EXPECT_FALSE(cache->find_exact(SimplifiedCache::key_for(cut, 30, true)).has_value());
  EXPECT_FALSE(cache->find_reusable(cut, 0.01, nullptr, 30, nullptr, true).has_value());
  EXPECT_TRUE(cache->find_reusable(cut, 0.01, nullptr, 30, nullptr, false).has_value());
  auto with = cache->insert(cut, write_file(dir / "b.drc", 100, 'b'), 60, 0.01, 30, true);
  ASSERT_TRUE(with.is_ok()) << with.status().message();
  EXPECT_TRUE(with->exact_normals);
  auto hit = cache->find_reusable(cut, 0.01, nullptr, 30, nullptr, true);
  ASSERT_TRUE(hit.has_value());
  EXPECT_EQ(hit->triangles, 60u);
  EXPECT_EQ(cache->find_reusable(cut, 0.01, nullptr, 30, nullptr, false)->triangles, 50u);
}

// The normals' quantisation follows the materials (a glossier scene asks
// for more bits): an exact hit needs the same bits, a reused entry at least
// as many, and an entry that does not record them is not reused where bits
// are asked for. The bits recorded come back with the entry.
TEST(SimplifiedCache, NormalBitsAreAskedForAndRecorded) {
  fs::path dir = fresh_dir("normal-bits");
  auto cache = SimplifiedCache::open(dir, 1 << 20);
  ASSERT_TRUE(cache.is_ok());
  Cut cut = make_cut(9, {{3, 5}});
  EXPECT_NE(SimplifiedCache::key_for(cut, 30, false, 10), SimplifiedCache::key_for(cut, 30, false, 14));
  ASSERT_TRUE(cache->insert(cut, write_file(dir / "a.drc", 100, 'a'), 50, 0.01, 30, false, 10, 21).is_ok());
  EXPECT_FALSE(cache->find_exact(SimplifiedCache::key_for(cut, 30, false, 14)).has_value());
  EXPECT_FALSE(cache->find_reusable(cut, 0.01, nullptr, 30, nullptr, false, 14).has_value());
  auto coarser = cache->find_reusable(cut, 0.01, nullptr, 30, nullptr, false, 8);
  ASSERT_TRUE(coarser.has_value());
  EXPECT_EQ(coarser->normal_bits, 10);
  EXPECT_EQ(coarser->position_bits, 21);
  auto exact = cache->find_exact(SimplifiedCache::key_for(cut, 30, false, 10));
  ASSERT_TRUE(exact.has_value());
  EXPECT_EQ(exact->position_bits, 21);
  // An entry without recorded bits (0) serves only where none are asked for.
  ASSERT_TRUE(cache->insert(cut, write_file(dir / "b.drc", 100, 'b'), 40, 0.01, 25, false).is_ok());
  EXPECT_FALSE(cache->find_reusable(cut, 0.01, nullptr, 25, nullptr, false, 8).has_value());
  EXPECT_TRUE(cache->find_reusable(cut, 0.01, nullptr, 25, nullptr, false).has_value());
}

TEST(SimplifiedCache, CheckoutSurvivesEviction) {
  fs::path dir = fresh_dir("checkout");
  auto cache = SimplifiedCache::open(dir, 1500);
  ASSERT_TRUE(cache.is_ok());
  Cut a = make_cut(1, {{1, 1}}), b = make_cut(1, {{1, 2}});
  auto ea = cache->insert(a, write_file(dir / "a.drc", 1000, 'a'), 1, 0.001);
  ASSERT_TRUE(ea.is_ok());
  ASSERT_TRUE(cache->checkout(*ea, dir / "mine.drc").is_ok());
  ASSERT_TRUE(cache->insert(b, write_file(dir / "b.drc", 1000, 'b'), 1, 0.001).is_ok());  // evicts a
  EXPECT_FALSE(fs::exists(ea->mesh));
  EXPECT_EQ(fs::file_size(dir / "mine.drc"), 1000u);
}

TEST(SimplifiedCache, EvictsLeastRecentlyUsed) {
  fs::path dir = fresh_dir("evict");
  auto cache = SimplifiedCache::open(dir, 5000);
  ASSERT_TRUE(cache.is_ok());
  Cut a = make_cut(1, {{1, 1}}), b = make_cut(1, {{1, 2}}), c = make_cut(1, {{1, 3}});
  ASSERT_TRUE(cache->insert(a, write_file(dir / "a.drc", 2000, 'a'), 1, 0.001).is_ok());
  ASSERT_TRUE(cache->insert(b, write_file(dir / "b.drc", 2000, 'b'), 1, 0.001).is_ok());
  auto ea = cache->find_exact(SimplifiedCache::key_for(a));
  ASSERT_TRUE(ea.has_value());
  cache->touch(*ea);  // a is now more recent than b
  ASSERT_TRUE(cache->insert(c, write_file(dir / "c.drc", 2000, 'c'), 1, 0.001).is_ok());
  EXPECT_TRUE(cache->find_exact(SimplifiedCache::key_for(a)).has_value());
  EXPECT_FALSE(cache->find_exact(SimplifiedCache::key_for(b)).has_value());
  EXPECT_TRUE(cache->find_exact(SimplifiedCache::key_for(c)).has_value());
}

// A scene of two meshes whose entries fit the limit one at a time only:
// inserting the second must not evict the first, which the same view uses,
// or each run of the view would miss both in turn (found by a bug hunt).
TEST(SimplifiedCache, AViewsEntriesAreHeldWhileItInsertsItsOthers) {
  fs::path dir = fresh_dir("held");
  auto cache = SimplifiedCache::open(dir, 3500);  // entries count their .drc, .cut and .json
  ASSERT_TRUE(cache.is_ok());
  Cut old = make_cut(1, {{1, 3}}), teapot = make_cut(1, {{1, 1}}), bottle = make_cut(1, {{1, 2}});
  ASSERT_TRUE(cache->insert(old, write_file(dir / "o.drc", 1000, 'o'), 1, 0.001).is_ok());
  // The view: the teapot's entry (a hit, or just made), then the bottle's.
  cache->release_held();
  auto t = cache->insert(teapot, write_file(dir / "t.drc", 2000, 't'), 1, 0.001);
  ASSERT_TRUE(t.is_ok());
  cache->hold(t->key);
  auto b = cache->insert(bottle, write_file(dir / "b.drc", 2000, 'b'), 1, 0.001);
  ASSERT_TRUE(b.is_ok());
  cache->hold(b->key);
  EXPECT_TRUE(cache->find_exact(t->key).has_value());  // held, though over the limit together
  EXPECT_TRUE(cache->find_exact(b->key).has_value());
  EXPECT_FALSE(cache->find_exact(SimplifiedCache::key_for(old)).has_value());  // not held: evicted
  // The next view holds nothing yet: the limit applies again.
  cache->release_held();
  auto other = cache->insert(make_cut(1, {{1, 4}}), write_file(dir / "x.drc", 2000, 'x'), 1, 0.001);
  ASSERT_TRUE(other.is_ok());
  EXPECT_FALSE(cache->find_exact(t->key).has_value());
  EXPECT_FALSE(cache->find_exact(b->key).has_value());
  EXPECT_TRUE(cache->find_exact(other->key).has_value());
}

TEST(SimplifiedCache, LeftoversOfAKilledRunAreIgnored) {
  fs::path dir = fresh_dir("killed");
  auto cache = SimplifiedCache::open(dir, 1 << 20);
  ASSERT_TRUE(cache.is_ok());
  Cut cut = make_cut(3, {{2, 2}});
  const std::string key = SimplifiedCache::key_for(cut);
  // A run killed after writing the mesh and cut but before the metadata,
  // and a temporary file it never renamed.
  write_file(dir / "simplified" / (key + ".drc"), 100, 'x');
  write_file(dir / "simplified" / (key + ".drc.tmp-123-0-1"), 50, 'y');
  EXPECT_FALSE(cache->find_exact(key).has_value());
  EXPECT_TRUE(cache->entries().empty());
  // A later run inserts the same key cleanly.
  ASSERT_TRUE(cache->insert(cut, write_file(dir / "new.drc", 100, 'z'), 7, 0.001).is_ok());
  auto hit = cache->find_exact(key);
  ASSERT_TRUE(hit.has_value());
  EXPECT_EQ(hit->triangles, 7u);
}

}  // namespace
}  // namespace raylod
