// The parts of core/cluster that decide without MPI: how gather_blocks
// splits a rank's blocks into messages, and which transport raylod names for
// Open MPI before MPI_Init. (tests/cluster/mpi_check.sh runs raylod itself
// under mpirun.)
#include <gtest/gtest.h>

#include <map>
#include <string>

#include "core/cluster.h"

namespace raylod::cluster {
namespace {

uint64_t total(const std::vector<Block>& blocks) {
  uint64_t n = 0;
  for (const Block& b : blocks) n += b.count;
  return n;
}

TEST(SplitBlocks, SmallBlocksStayInOneMessage) {
  const std::vector<Block> blocks = {{0, 3}, {10, 4}, {20, 2}};
  const auto messages = split_blocks(blocks, 100);
  ASSERT_EQ(messages.size(), 1u);
  ASSERT_EQ(messages[0].size(), 3u);
  EXPECT_EQ(messages[0][1].first, 10u);
  EXPECT_EQ(messages[0][1].count, 4u);
}

TEST(SplitBlocks, ABlockIsCutWhereAMessageFills) {
  // 3 + 4 + 2 elements in messages of at most 5: [0,3) [10,12) | [12,14) [20,22) .
  const std::vector<Block> blocks = {{0, 3}, {10, 4}, {20, 2}};
  const auto messages = split_blocks(blocks, 5);
  ASSERT_EQ(messages.size(), 2u);
  EXPECT_EQ(total(messages[0]), 5u);
  EXPECT_EQ(total(messages[1]), 4u);
  EXPECT_EQ(messages[0][1].first, 10u);
  EXPECT_EQ(messages[0][1].count, 2u);
  EXPECT_EQ(messages[1][0].first, 12u);
  EXPECT_EQ(messages[1][0].count, 2u);
  EXPECT_EQ(messages[1][1].first, 20u);
}

TEST(SplitBlocks, EveryElementOnceInOrderForAnyLimit) {
  std::vector<Block> blocks;
  for (uint64_t i = 0; i < 40; ++i) blocks.push_back({i * 100 + i % 7, 1 + (i * 37) % 23});
  for (uint64_t most : {1u, 2u, 7u, 23u, 64u, 1000u}) {
    const auto messages = split_blocks(blocks, most);
    std::vector<uint64_t> want, got;
    for (const Block& b : blocks)
      for (uint64_t k = 0; k < b.count; ++k) want.push_back(b.first + k);
    for (const auto& m : messages) {
      EXPECT_LE(total(m), most);
      EXPECT_GT(total(m), 0u);
      for (const Block& b : m)
        for (uint64_t k = 0; k < b.count; ++k) got.push_back(b.first + k);
    }
    EXPECT_EQ(got, want) << "most " << most;
    for (size_t i = 0; i + 1 < messages.size(); ++i) EXPECT_EQ(total(messages[i]), most) << "most " << most;
  }
  EXPECT_TRUE(split_blocks({}, 5).empty());
}

TEST(GatherBlocks, OneProcessLeavesTheBufferAsItIs) {
  std::vector<float> buffer = {1, 2, 3, 4};
  gather_blocks(buffer.data(), sizeof(float), [](int) { return std::vector<Block>{{0, 4}}; });
  EXPECT_EQ(buffer, (std::vector<float>{1, 2, 3, 4}));
}

std::vector<std::pair<std::string, std::string>> transport(const std::map<std::string, std::string>& vars) {
  return single_node_transport([&](const char* name) -> const char* {
    const auto it = vars.find(name);
    return it == vars.end() ? nullptr : it->second.c_str();
  });
}

TEST(SingleNodeTransport, SharedMemoryWhenEveryRankIsOnThisNode) {
  const auto t = transport({{"OMPI_COMM_WORLD_SIZE", "2"}, {"OMPI_COMM_WORLD_LOCAL_SIZE", "2"}});
  ASSERT_EQ(t.size(), 2u);
  EXPECT_EQ(t[0], std::make_pair(std::string("OMPI_MCA_pml"), std::string("ob1")));
  EXPECT_EQ(t[1], std::make_pair(std::string("OMPI_MCA_btl"), std::string("self,vader")));
}

TEST(SingleNodeTransport, NothingAcrossNodesOrWhenTheUserChose) {
  const std::map<std::string, std::string> one_node = {{"OMPI_COMM_WORLD_SIZE", "4"},
                                                       {"OMPI_COMM_WORLD_LOCAL_SIZE", "4"}};
  EXPECT_EQ(transport(one_node).size(), 2u);
  EXPECT_TRUE(transport({{"OMPI_COMM_WORLD_SIZE", "4"}, {"OMPI_COMM_WORLD_LOCAL_SIZE", "2"}}).empty());
  EXPECT_TRUE(transport({}).empty());                               // not Open MPI's mpirun
  EXPECT_TRUE(transport({{"OMPI_COMM_WORLD_SIZE", "2"}}).empty());  // no local size
  for (const char* chosen : {"OMPI_MCA_pml", "OMPI_MCA_btl", "OMPI_MCA_mtl"}) {
    auto vars = one_node;
    vars[chosen] = "ucx";
    EXPECT_TRUE(transport(vars).empty()) << chosen;
  }
  auto off = one_node;
  off["RAYLOD_MPI_AUTO_TRANSPORT"] = "0";
  EXPECT_TRUE(transport(off).empty());
  off["RAYLOD_MPI_AUTO_TRANSPORT"] = "1";
  EXPECT_EQ(transport(off).size(), 2u);
}

}  // namespace
}  // namespace raylod::cluster
