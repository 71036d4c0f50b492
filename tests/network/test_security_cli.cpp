// The keyed deployment with the real programs over loopback (README "Deployment with keys"):
// cslam-keygen makes the keys, cslam-server with --curve-secret/--clients-allowed serves a keyed
// cslam-client and ignores one without keys; without keys a wide --bind is refused.
#include <filesystem>

#include <gtest/gtest.h>

#include "common/run_program.h"
#include "net_test_util.h"

namespace cslam {
namespace {

const std::string kBin = CSLAM_BIN_DIR;

TEST(SecurityCli, WideBindWithoutKeysIsRefused) {
  const auto r = test::run_program("cslam-server", "--bind 'tcp://*:0' --http off --no-slam");
  EXPECT_EQ(r.status, 2) << r.output;
  EXPECT_NE(r.output.find("--curve-secret"), std::string::npos) << r.output;
  const auto half = test::run_program("cslam-server", "--curve-secret /nonexistent --http off --no-slam");
  EXPECT_EQ(half.status, 2) << half.output;
}

TEST(SecurityCli, TimestampJumpBoundIsAnOption) {
  const auto r = test::run_program("cslam-server", "--max-timestamp-jump -1 --http off --no-slam");
  EXPECT_EQ(r.status, 2) << r.output;
  EXPECT_NE(r.output.find("--max-timestamp-jump must be >= 0"), std::string::npos) << r.output;
}

TEST(SecurityCli, KeygenWritesKeysAndDoesNotOverwrite) {
  const std::string dir = test::scratch_dir("keygen");
  auto r = test::run_program("cslam-keygen", "--out " + dir + "/robot --client-ids 3,4");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_TRUE(std::filesystem::exists(dir + "/robot.key"));
  EXPECT_NE(test::read_lines(dir + "/robot.pub").back().find("client-ids = 3,4"), std::string::npos);
  r = test::run_program("cslam-keygen", "--out " + dir + "/robot");
  EXPECT_EQ(r.status, 2) << r.output;  // exists
  r = test::run_program("cslam-keygen", "--out " + dir + "/robot --force --client-ids 70000");
  EXPECT_EQ(r.status, 2) << r.output;  // id out of range
  std::filesystem::remove_all(dir);
}

TEST(SecurityCli, KeyedServerServesAKeyedClientOnly) {
  const std::string dir = test::scratch_dir("keyed");
  const std::string data = dir + "/data";
  test::write_tiny_dataset(data, 12);
  std::filesystem::create_directories(dir + "/keys/clients");
  ASSERT_EQ(test::run_program("cslam-keygen", "--out " + dir + "/keys/server").status, 0);
  ASSERT_EQ(test::run_program("cslam-keygen", "--out " + dir + "/robot1 --client-ids 1").status, 0);
  std::filesystem::copy_file(dir + "/robot1.pub", dir + "/keys/clients/robot1.pub");
  test::ChildProcess server(
      {kBin + "/cslam-server", "--bind", "tcp://127.0.0.1:*", "--endpoint-file", dir + "/endpoint", "--out-dir",
       dir + "/out", "--no-slam", "--http", "off", "--clients", "1", "--exit-when-done", "--curve-secret",
       dir + "/keys/server.key", "--clients-allowed", dir + "/keys/clients"},
      dir + "/server.log");
  const auto endpoint = test::wait_for_file_line(dir + "/endpoint", 60);
  ASSERT_TRUE(endpoint);
  // Without keys: no answer at all (the handshake fails), so the client gives up.
  test::ChildProcess plain({kBin + "/cslam-client", "--server", *endpoint, "--id", "1", "--dataset", data, "--rate",
                            "max", "--reply-timeout", "2"},
                           dir + "/plain.log");
  const auto plain_exit = plain.wait(60);
  ASSERT_TRUE(plain_exit);
  EXPECT_NE(*plain_exit, 0);
  test::ChildProcess keyed({kBin + "/cslam-client", "--server", *endpoint, "--id", "1", "--dataset", data, "--rate",
                            "max", "--server-key", dir + "/keys/server.pub", "--curve-secret", dir + "/robot1.key"},
                           dir + "/keyed.log");
  const auto keyed_exit = keyed.wait(120);
  ASSERT_TRUE(keyed_exit);
  EXPECT_EQ(*keyed_exit, 0);
  const auto server_exit = server.wait(60);
  ASSERT_TRUE(server_exit);
  EXPECT_EQ(*server_exit, 0);
  EXPECT_EQ(test::trajectory_lines(dir + "/out/client_1.txt").size(), 12u);
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace cslam
