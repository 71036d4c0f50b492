// Programs and tests allocate through tcmalloc (cmake/CslamTargets.cmake, cslam_allocator): this
// test binary is linked as they are, and the main programs are checked for the library.
#include <dlfcn.h>

#include <array>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>

#include <gtest/gtest.h>

namespace {

std::string run_and_capture(const std::string& command) {
  std::unique_ptr<FILE, int (*)(FILE*)> pipe(popen(command.c_str(), "r"), pclose);
  if (!pipe) return {};
  std::string out;
  std::array<char, 4096> buf;
  for (std::size_t n; (n = std::fread(buf.data(), 1, buf.size(), pipe.get())) > 0;) out.append(buf.data(), n);
  return out;
}

}  // namespace

TEST(Allocator, MallocIsTcmallocInThisProcess) {
  void* tc = dlsym(RTLD_DEFAULT, "tc_malloc");
  ASSERT_NE(tc, nullptr) << "tcmalloc is not loaded";
  EXPECT_EQ(dlsym(RTLD_DEFAULT, "malloc"), tc) << "malloc does not resolve to tcmalloc";
  void* p = std::malloc(640 * 480 * 3);
  ASSERT_NE(p, nullptr);
  std::free(p);
}

TEST(Allocator, ProgramsLoadTcmalloc) {
  for (const char* program : {"cslam-server", "cslam-client", "cslam-slam", "cslam-experiment", "cslam-recon"}) {
    const std::string path = std::string(CSLAM_BIN_DIR) + "/" + program;
    const std::string libs = run_and_capture("ldd '" + path + "' 2>&1");
    EXPECT_NE(libs.find("libtcmalloc_minimal"), std::string::npos) << program << ":\n" << libs;
  }
}
