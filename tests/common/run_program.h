#pragma once
// Running the project's programs from tests, as a user would, and temporary folders.
#include <array>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>

#include <sys/wait.h>
#include <unistd.h>

namespace cslam::test {

struct RunResult {
  int status = -1;
  std::string output;  // stdout and stderr
};

// Runs a shell command; captures its output (stdout and stderr) and exit status.
inline RunResult run_command(const std::string& command) {
  const std::string cmd = command + " 2>&1";
  RunResult r;
  FILE* pipe = popen(cmd.c_str(), "r");
  if (!pipe) return r;
  std::array<char, 512> buf{};
  while (fgets(buf.data(), int(buf.size()), pipe)) r.output += buf.data();
  const int status = pclose(pipe);
  r.status = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

// Runs build/bin/<program> <args> through the shell; captures its output and exit status.
inline RunResult run_program(const std::string& program, const std::string& args) {
  return run_command(std::string(CSLAM_BIN_DIR) + "/" + program + " " + args);
}

// cslam-synth's small test scene in `out`: `--preset test-small` with `args` (e.g. "--frames 60 --seed 5").
inline RunResult render_test_scene(const std::string& out, const std::string& args) {
  return run_program("cslam-synth", "--preset test-small " + args + " --out " + out + " --log-level warn");
}

// A fresh folder under the system temp dir, removed when the object goes away.
class TempDir {
 public:
  explicit TempDir(const std::string& name)
      : path_(std::filesystem::temp_directory_path() / (name + "_" + std::to_string(::getpid()))) {
    std::filesystem::remove_all(path_);
    std::filesystem::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  std::string str() const { return path_.string(); }
  std::string operator/(const std::string& rel) const { return (path_ / rel).string(); }

 private:
  std::filesystem::path path_;
};

}  // namespace cslam::test
