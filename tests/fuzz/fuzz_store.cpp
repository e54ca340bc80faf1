// libFuzzer target: opening an octree store (header, node and page tables)
// and reading its first pages. The first input byte chooses the mode, the rest
// is the store file:
//   even: the bytes as they are (the magic, version and CRCs are checked first);
//   odd:  the checksums are repaired before opening (the header CRC, and, if
//         the header then reads, the node table, page table and boundary list CRCs and every page's
//         CRC), so that mutations reach the checks behind the checksums.
#include <cstring>
#include <string>

#include "core/system.h"
#include "fuzz_input.h"
#include "streaming/octree_format.h"
#include "streaming/octree_store.h"

namespace {

using namespace raylod;

uint32_t crc_of(const std::string& bytes, uint64_t offset, uint64_t length) {
  if (offset > bytes.size() || length > bytes.size() - offset) return 0;
  return crc32c(bytes.data() + offset, length);
}

void repair_checksums(std::string& bytes) {
  // Header: magic, version, blob_bytes, blob, CRC-32C of all before.
  if (bytes.size() < 16) return;
  uint32_t blob = 0;
  std::memcpy(&blob, bytes.data() + 12, 4);
  if (blob > bytes.size() || 16 + uint64_t(blob) + 4 > bytes.size()) return;
  const uint32_t crc = crc32c(bytes.data(), 16 + blob);
  std::memcpy(bytes.data() + 16 + blob, &crc, 4);
  // The tables: decode the header with the store's own code, fix their CRCs, encode it again.
  StoreHeader h;
  store_format::Layout l;
  {
    fuzz::MemFile file(reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size());
    if (!store_format::read_header(file.fd(), file.path(), h, l)) return;
  }
  if (l.node_table_bytes > bytes.size() || l.page_count > bytes.size() / sizeof(PageInfo) ||
      l.boundary_count > bytes.size() / 8)
    return;
  l.node_table_crc = crc_of(bytes, l.node_table_offset, l.node_table_bytes);
  l.boundary_crc = crc_of(bytes, l.boundary_offset, l.boundary_count * 8);
  const uint64_t page_table_bytes = l.page_count * sizeof(PageInfo);
  if (l.page_table_offset <= bytes.size() && page_table_bytes <= bytes.size() - l.page_table_offset) {
    for (uint64_t i = 0; i < l.page_count; ++i) {
      PageInfo p;
      char* at = bytes.data() + l.page_table_offset + i * sizeof(PageInfo);
      std::memcpy(&p, at, sizeof p);
      // One CRC covers a page's bytes.
      if (p.offset <= bytes.size() && p.bytes <= bytes.size() - p.offset) p.checksum = crc32c(bytes.data() + p.offset, p.bytes);
      std::memcpy(at, &p, sizeof p);
    }
  }
  l.page_table_crc = crc_of(bytes, l.page_table_offset, page_table_bytes);
  const std::string header = store_format::encode_header(h, l);
  if (header.size() == 16 + uint64_t(blob) + 4) bytes.replace(0, header.size(), header);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  std::string bytes(reinterpret_cast<const char*>(data) + 1, size - 1);
  if (data[0] & 1) repair_checksums(bytes);
  fuzz::MemFile file(reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size());
  auto opened = OctreeStore::open(file.path());
  if (!opened) {
    RAYLOD_FUZZ_CHECK(!opened.status().message().empty());
    return 0;
  }
  const OctreeStore& store = **opened;
  const StoreHeader& h = store.header();
  RAYLOD_FUZZ_CHECK(h.root_size > 0 && h.quadric_depth >= 0);
  for (int level = 0; level <= h.quadric_depth; ++level)
    for (const NodeRecord& n : store.level(level))
      RAYLOD_FUZZ_CHECK(store.find(CellKey{uint32_t(level), n.code}) == &n);
  // A few pages; a checksum mismatch here cannot be recorded beside a memfd, which is fine.
  TriangleBatch batch;
  for (size_t i = 0; i < std::min<size_t>(store.pages().size(), 4); ++i) {
    Status read = store.read_page(i, batch);
    if (read) RAYLOD_FUZZ_CHECK(batch.size() == store.pages()[i].triangle_count);
    else RAYLOD_FUZZ_CHECK(!read.message().empty());
  }
  return 0;
}
