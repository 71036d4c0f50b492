// Programs and tests allocate through tcmalloc (cmake/CslamTargets.cmake, cslam_allocator): this
// test binary is linked as they are, and the main programs are checked for the library.
#include <dlfcn.h>

#include <cstdlib>
#include <string>

#include <gtest/gtest.h>

#include "common/run_program.h"

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
    const std::string libs = cslam::test::run_command("ldd '" + path + "'").output;
    EXPECT_NE(libs.find("libtcmalloc_minimal"), std::string::npos) << program << ":\n" << libs;
  }
}
