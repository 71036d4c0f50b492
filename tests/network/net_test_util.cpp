#include "net_test_util.h"

#include <csignal>
#include <cstdio>
#include <fcntl.h>
#include <random>
#include <sys/wait.h>
#include <unistd.h>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "common/run_program.h"
#include "geometry/camera_io.h"

namespace cslam::test {

PinholeCamera small_camera() {
  PinholeCamera c;
  c.name = "small";
  c.width = 64;
  c.height = 48;
  c.fx = c.fy = 50;
  c.cx = 31.5;
  c.cy = 23.5;
  return c;
}

PinholeCamera write_tiny_dataset(const std::string& dir, int frames, int width, int height, unsigned seed) {
  namespace fs = std::filesystem;
  fs::create_directories(dir + "/rgb");
  fs::create_directories(dir + "/depth");
  std::ofstream rgb_list(dir + "/rgb.txt"), depth_list(dir + "/depth.txt");
  rgb_list << "# timestamp filename\n";
  depth_list << "# timestamp filename\n";
  cv::RNG rng(seed);
  for (int i = 0; i < frames; ++i) {
    cv::Mat bgr(height, width, CV_8UC3);
    rng.fill(bgr, cv::RNG::UNIFORM, 0, 256);
    cv::GaussianBlur(bgr, bgr, cv::Size(3, 3), 1.0);
    cv::Mat depth(height, width, CV_16UC1);
    for (int y = 0; y < height; ++y)
      for (int x = 0; x < width; ++x)
        depth.at<std::uint16_t>(y, x) = (x + y + i) % 17 == 0 ? 0 : std::uint16_t(5000 + 10 * x + 3 * y + i);
    const double t = 1000.0 + i / 30.0;
    char name[64];
    std::snprintf(name, sizeof name, "%.6f.png", t);
    cv::imwrite(dir + "/rgb/" + name, bgr);
    cv::imwrite(dir + "/depth/" + name, depth);
    rgb_list << std::fixed << t << " rgb/" << name << "\n";
    depth_list << std::fixed << t << " depth/" << name << "\n";
  }
  PinholeCamera cam;
  cam.name = "tiny";
  cam.width = width;
  cam.height = height;
  cam.fx = cam.fy = 50.0;
  cam.cx = (width - 1) / 2.0;
  cam.cy = (height - 1) / 2.0;
  save_camera_file(cam, dir + "/camera.yaml");
  return cam;
}

std::string render_small_scene(const std::string& out) {
  const auto synth =
      run_program("cslam-synth", "--preset test-small --seed 7 --robots 1 --out " + out + " --log-level warn");
  if (synth.status != 0) throw std::runtime_error("cslam-synth failed: " + synth.output);
  return out + "/robot_1";
}

std::string scratch_dir(const std::string& name) {
  const auto base = std::filesystem::temp_directory_path() /
                    ("cslam-net-" + name + "-" + std::to_string(::getpid()) + "-" +
                     std::to_string(std::chrono::steady_clock::now().time_since_epoch().count()));
  std::filesystem::create_directories(base);
  return base.string();
}

ScratchDir::~ScratchDir() {
  if (::testing::Test::HasFailure()) {
    std::fprintf(stderr, "kept %s for the failed test\n", path_.c_str());
    return;
  }
  std::error_code ec;
  std::filesystem::remove_all(path_, ec);
}

std::vector<std::string> read_lines(const std::string& path) {
  std::ifstream in(path);
  std::vector<std::string> lines;
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

std::vector<std::string> trajectory_lines(const std::string& path) {
  std::vector<std::string> out;
  for (auto& l : read_lines(path))
    if (!l.empty() && l[0] != '#') out.push_back(l);
  return out;
}

RawPeer::RawPeer(zmq::context_t& context, const std::string& endpoint) : socket_(context, zmq::socket_type::dealer) {
  socket_.set(zmq::sockopt::linger, 0);
  socket_.connect(endpoint);
}

void RawPeer::send_bytes(const std::string& bytes) { socket_.send(zmq::buffer(bytes), zmq::send_flags::none); }

std::optional<wire::ServerMessage> RawPeer::receive(int timeout_ms) {
  zmq::pollitem_t item{socket_.handle(), 0, ZMQ_POLLIN, 0};
  zmq::poll(&item, 1, std::chrono::milliseconds(timeout_ms));
  if (!(item.revents & ZMQ_POLLIN)) return std::nullopt;
  zmq::message_t m;
  if (!socket_.recv(m, zmq::recv_flags::none)) return std::nullopt;
  return wire::parse_server_message(m.data(), m.size(), "test");
}

wire::ClientMessage make_hello(ClientId id, const PinholeCamera& camera) {
  ClientInfo info;
  info.id = id;
  info.name = "peer" + std::to_string(id);
  info.camera = camera;
  wire::ClientMessage m;
  *m.mutable_hello() = wire::to_hello(info);
  return m;
}

wire::ClientMessage make_frame(ClientId id, std::uint64_t seq, double timestamp, const PinholeCamera& camera,
                               const CodecOptions& codecs) {
  RgbdFrame f;
  f.client = id;
  f.seq = seq;
  f.timestamp = timestamp;
  f.bgr = cv::Mat(camera.height, camera.width, CV_8UC3, cv::Scalar(10, 20, 30));
  f.depth = cv::Mat(camera.height, camera.width, CV_16UC1, cv::Scalar(4000));
  wire::ClientMessage m;
  ImageEncoder images(codecs);
  wire::to_wire_frame(f, images, m.mutable_frame());
  return m;
}

InProcessServer::InProcessServer(server::ReceiverConfig config, SystemConfig system_config) {
  if (config.bind == server::ReceiverConfig().bind) config.bind = "tcp://127.0.0.1:*";  // a free port
  auto user_callback = system_config.on_frame_done;
  system_config.on_frame_done = [this, user_callback](const FrameDone& d) {
    if (user_callback) user_callback(d);
    done_.push(d);
  };
  system_ = std::make_unique<CollaborativeSystem>(system_config);
  receiver_ = std::make_unique<server::Receiver>(context_, config, *system_, done_, stop_pipe_);
  receiver_->set_status_board(&board_);
  thread_ = std::thread([this] {
    receiver_->run();
    finished_ = true;
  });
}

InProcessServer::~InProcessServer() {
  stop();
  system_->finish();
}

void InProcessServer::stop() {
  stop_pipe_.notify();
  if (thread_.joinable()) thread_.join();
}

bool InProcessServer::wait_done(double timeout_s) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  while (!finished_ && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  if (finished_ && thread_.joinable()) thread_.join();
  return finished_;
}

ChildProcess::ChildProcess(const std::vector<std::string>& argv, const std::string& log_path) {
  pid_ = ::fork();
  if (pid_ == 0) {
    const int fd = ::open(log_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (fd >= 0) {
      ::dup2(fd, 1);
      ::dup2(fd, 2);
    }
    std::vector<char*> args;
    for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
    args.push_back(nullptr);
    ::execv(args[0], args.data());
    ::_exit(127);
  }
}

ChildProcess::~ChildProcess() {
  if (pid_ > 0 && !reaped_) {
    ::kill(pid_, SIGKILL);
    ::waitpid(pid_, nullptr, 0);
  }
}

std::optional<int> ChildProcess::wait(double timeout_s) {
  if (reaped_) return std::nullopt;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  for (;;) {
    int status = 0;
    const int r = ::waitpid(pid_, &status, WNOHANG);
    if (r == pid_) {
      reaped_ = true;
      if (WIFEXITED(status)) return WEXITSTATUS(status);
      return 128 + (WIFSIGNALED(status) ? WTERMSIG(status) : 0);
    }
    if (std::chrono::steady_clock::now() > deadline) {
      ::kill(pid_, SIGKILL);
      ::waitpid(pid_, nullptr, 0);
      reaped_ = true;
      return std::nullopt;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
}

void ChildProcess::terminate() {
  if (pid_ > 0 && !reaped_) ::kill(pid_, SIGTERM);
}

std::optional<std::string> wait_for_file_line(const std::string& path, double timeout_s) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  while (std::chrono::steady_clock::now() < deadline) {
    if (std::filesystem::exists(path)) {
      const auto lines = read_lines(path);
      if (!lines.empty() && !lines[0].empty()) return lines[0];
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return std::nullopt;
}

}  // namespace cslam::test
