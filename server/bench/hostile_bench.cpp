// cslam-bench-hostile: the hardening figures of docs/security.md, against a real cslam-server
// process on loopback. One run:
//   1. starts cslam-server (--no-slam unless --slam; HTTP on a free port);
//   2. a good client streams --frames 640x480 frames (JPEG + zstd) at full speed, while (with
//      --hostile) a hostile peer sends PNG bombs, hijack hellos, seq 2^64-1 frames, huge-camera
//      hellos, random bytes and 1000 hellos with new ids, 50 HTTP slowloris connections are
//      open, and header floods and 1 MB chunked POSTs repeat; /api/status is probed meanwhile;
//   3. stops the server with SIGTERM and reads network_stats.json.
// Prints one JSON line: receive-loop and per-message stall maxima, peak RSS (VmHWM), threads after
// the 1000 hellos, /api/status latency percentiles, the good client's frames acknowledged.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>
#include <zlib.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <random>
#include <thread>

#include <nlohmann/json.hpp>

#include "client/frame_sender.h"
#include "core/cli.h"
#include "core/error.h"
#include "core/stopwatch.h"
#include "core/stats.h"
#include "server/bench/hostile_payloads.h"

namespace {

using Clock = std::chrono::steady_clock;
using cslam::ClientId;

std::string status_field(int pid, const std::string& key) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/status");
  std::string line;
  while (std::getline(in, line))
    if (line.rfind(key + ":", 0) == 0) return line.substr(key.size() + 1);
  return "";
}
long status_number(int pid, const std::string& key) {
  const std::string v = status_field(pid, key);
  return v.empty() ? -1 : std::stol(v);
}

std::string wait_file(const std::string& path, double timeout_s) {
  const auto deadline = Clock::now() + std::chrono::duration<double>(timeout_s);
  while (Clock::now() < deadline) {
    std::ifstream in(path);
    std::string line;
    if (in && std::getline(in, line) && !line.empty()) return line;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  throw std::runtime_error("no " + path + " within " + std::to_string(timeout_s) + " s");
}

int connect_http(int port) {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_port = htons(std::uint16_t(port));
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (::connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0) {
    ::close(fd);
    return -1;
  }
  return fd;
}

// One GET /api/status on a fresh connection; returns ms, or -1 on failure.
double probe_status(int port) {
  const cslam::Stopwatch t;
  const int fd = connect_http(port);
  if (fd < 0) return -1;
  const std::string req = "GET /api/status HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n";
  if (::send(fd, req.data(), req.size(), MSG_NOSIGNAL) < 0) {
    ::close(fd);
    return -1;
  }
  timeval tv{10, 0};
  ::setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
  std::string got;
  char buf[8192];
  for (ssize_t n; (n = ::recv(fd, buf, sizeof buf, 0)) > 0;) got.append(buf, std::size_t(n));
  ::close(fd);
  return got.rfind("HTTP/1.1 200", 0) == 0 ? t.ms() : -1;
}

cslam::PinholeCamera vga() {
  cslam::PinholeCamera c;
  c.name = "bench";
  c.width = 640;
  c.height = 480;
  c.fx = c.fy = 525;
  c.cx = 319.5;
  c.cy = 239.5;
  c.depth_factor = 5000;
  return c;
}

cslam::wire::ClientMessage hello(ClientId id, const cslam::PinholeCamera& cam) {
  cslam::ClientInfo info;
  info.id = id;
  info.name = "h" + std::to_string(id);
  info.camera = cam;
  cslam::wire::ClientMessage m;
  *m.mutable_hello() = cslam::wire::to_hello(info);
  return m;
}

void send(zmq::socket_t& s, const cslam::wire::ClientMessage& m) {
  const std::string b = m.SerializeAsString();
  (void)s.send(zmq::buffer(b), zmq::send_flags::dontwait);
}

void drain(zmq::socket_t& s) {
  zmq::message_t m;
  while (s.recv(m, zmq::recv_flags::dontwait)) {
  }
}

// The hostile peer: every case of docs/security.md, repeated until `stop`.
void hostile(const std::string& endpoint, std::atomic<bool>& stop, long* threads_after_hellos, int server_pid) {
  zmq::context_t ctx(1);
  auto make_peer = [&] {
    zmq::socket_t p(ctx, zmq::socket_type::dealer);
    p.set(zmq::sockopt::linger, 0);
    p.set(zmq::sockopt::sndhwm, 100000);
    p.connect(endpoint);
    return p;
  };
  zmq::socket_t peer = make_peer(), bomber = make_peer(), flood = make_peer();
  const cslam::PinholeCamera cam = vga();
  std::mt19937 rng(7);
  send(bomber, hello(901, cam));  // a session of its own for the PNG bombs
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  // 1000 hellos with new ids (threads counted after them).
  for (ClientId id = 1000; id < 2000; ++id) send(flood, hello(id, cam));
  std::this_thread::sleep_for(std::chrono::seconds(3));
  drain(flood);
  *threads_after_hellos = status_number(server_pid, "Threads");
  const std::string bomb = cslam::hostile::png_bomb(640, 480, 256u << 20);
  cslam::PinholeCamera huge = cam;
  huge.width = huge.height = 8192;
  huge.cx = huge.cy = 4096;
  std::uint64_t seq = 1;
  while (!stop) {
    send(peer, hello(1, cam));  // the good client's id: refused as busy
    cslam::wire::ClientMessage f;
    cslam::wire::RgbdFrame* fr = f.mutable_frame();
    fr->set_client_id(1);
    fr->set_seq(~0ull);
    send(peer, f);
    send(peer, hello(900, huge));
    // PNG bombs on the bomber's session (each refused as corrupt, credit handed back).
    for (int i = 0; i < 3; ++i) {
      cslam::wire::ClientMessage b;
      cslam::wire::RgbdFrame* bf = b.mutable_frame();
      bf->set_client_id(901);
      bf->set_seq(seq++);
      for (cslam::wire::Image* img : {bf->mutable_rgb(), bf->mutable_depth()}) {
        img->set_width(640);
        img->set_height(480);
      }
      bf->mutable_rgb()->set_encoding(cslam::wire::RGB_PNG);
      bf->mutable_rgb()->set_data(bomb);
      bf->mutable_depth()->set_encoding(cslam::wire::DEPTH_RAW_U16LE);
      bf->mutable_depth()->set_data(std::string(640 * 480 * 2, '\0'));
      send(bomber, b);
    }
    std::string junk(1 + rng() % 4096, '\0');
    for (char& c : junk) c = char(rng());
    (void)peer.send(zmq::buffer(junk), zmq::send_flags::dontwait);
    drain(peer);
    drain(bomber);
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
}

// HTTP abuse beside the slowloris connections: a header flood (20 000 x 1 kB header lines until the
// server refuses) and a 1 MB chunked POST, repeated until `stop`.
void http_abuse(int port, std::atomic<bool>& stop) {
  const std::string header = "X-Flood: " + std::string(1000, 'a') + "\r\n";
  const std::string chunk = "4000\r\n" + std::string(0x4000, 'z') + "\r\n";
  while (!stop) {
    int fd = connect_http(port);
    if (fd >= 0) {
      std::string req = "GET /api/status HTTP/1.1\r\nHost: x\r\n";
      (void)::send(fd, req.data(), req.size(), MSG_NOSIGNAL);
      for (int i = 0; i < 20000 && ::send(fd, header.data(), header.size(), MSG_NOSIGNAL) > 0; ++i) {
      }
      ::close(fd);
    }
    fd = connect_http(port);
    if (fd >= 0) {
      const std::string post = "POST /api/reconstruction HTTP/1.1\r\nHost: x\r\nTransfer-Encoding: chunked\r\n\r\n";
      (void)::send(fd, post.data(), post.size(), MSG_NOSIGNAL);
      for (int i = 0; i < 64 && ::send(fd, chunk.data(), chunk.size(), MSG_NOSIGNAL) > 0; ++i) {
      }
      ::close(fd);
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
  }
}

int run(int argc, char** argv) {
  cslam::CliArgs cli("cslam-bench-hostile",
                     "Hardening figures of cslam-server under a hostile peer (docs/security.md).");
  cli.option("bin", "folder of cslam-server", "build/bin")
      .option("out", "scratch folder", "/tmp/cslam-bench-hostile")
      .option("frames", "frames the good client sends", "300")
      .option("slowloris", "HTTP connections that never finish their request", "50")
      .option("probes", "/api/status probes", "200")
      .flag("hostile", "run the hostile peer and the slowloris connections")
      .flag("slam", "run SLAM in the server (threads per client with real pipelines)");
  if (!cli.parse(argc, argv)) return 0;
  const std::string out = cli.get("out");
  std::filesystem::remove_all(out);
  std::filesystem::create_directories(out);
  const bool hostile_on = cli.flag_set("hostile");

  std::vector<std::string> args = {cli.get("bin") + "/cslam-server",
                                   "--bind",
                                   "tcp://127.0.0.1:*",
                                   "--endpoint-file",
                                   out + "/endpoint",
                                   "--http",
                                   "0",
                                   "--http-port-file",
                                   out + "/http_port",
                                   "--out-dir",
                                   out + "/run",
                                   "--log-level",
                                   "warn",
                                   "--max-clients",
                                   "64"};
  if (!cli.flag_set("slam")) args.push_back("--no-slam");
  const int pid = ::fork();
  if (pid == 0) {
    std::vector<char*> a;
    for (auto& s : args) a.push_back(s.data());
    a.push_back(nullptr);
    ::execv(a[0], a.data());
    ::_exit(127);
  }
  const std::string endpoint = wait_file(out + "/endpoint", 60);
  const int http_port = std::stoi(wait_file(out + "/http_port", 60));
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  const long threads_idle = status_number(pid, "Threads");

  cslam::client::SenderConfig cc;
  cc.server = endpoint;
  cc.info.id = 1;
  cc.info.name = "good";
  cc.info.camera = vga();
  cc.reply_timeout_s = 30;
  cslam::client::FrameSender sender(cc);
  sender.connect();  // before the hostile peer fills the session table

  std::atomic<bool> stop{false};
  long threads_after_hellos = -1;
  std::thread hostile_thread, http_abuse_thread;
  std::vector<int> slow;
  if (hostile_on) {
    for (int i = 0; i < cli.get_int("slowloris"); ++i) {
      const int fd = connect_http(http_port);
      const std::string partial = "GET /api/status HTTP/1.1\r\nHost: x\r\n";
      if (fd >= 0 && ::send(fd, partial.data(), partial.size(), MSG_NOSIGNAL) > 0) slow.push_back(fd);
    }
    hostile_thread = std::thread([&] { hostile(endpoint, stop, &threads_after_hellos, pid); });
    http_abuse_thread = std::thread([&] { http_abuse(http_port, stop); });
  }
  // /api/status probes while everything runs.
  std::vector<double> status_ms;
  int status_failed = 0;
  std::thread prober([&] {
    for (int i = 0; i < cli.get_int("probes") && !stop; ++i) {
      const double ms = probe_status(http_port);
      if (ms < 0)
        ++status_failed;
      else
        status_ms.push_back(ms);
      // Keep the slowloris connections trickling (each line used to reset httplib's timeout).
      if (i % 10 == 0)
        for (int fd : slow) (void)::send(fd, "X-T: 1\r\n", 8, MSG_NOSIGNAL | MSG_DONTWAIT);
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
  });

  cv::Mat bgr(480, 640, CV_8UC3), depth(480, 640, CV_16UC1);
  cv::RNG rng(3);
  rng.fill(bgr, cv::RNG::UNIFORM, 0, 256);
  rng.fill(depth, cv::RNG::UNIFORM, 500, 5000);
  cslam::RgbdFrame frame;
  frame.bgr = bgr;
  frame.depth = depth;
  const cslam::Stopwatch stream_time;
  for (int i = 0; i < cli.get_int("frames"); ++i) {
    frame.timestamp = i / 30.0;
    sender.send_frame(frame);
  }
  const bool all_acked = sender.goodbye(60);
  const double stream_s = stream_time.ms() / 1000;
  prober.join();
  stop = true;
  if (hostile_thread.joinable()) hostile_thread.join();
  if (http_abuse_thread.joinable()) http_abuse_thread.join();
  const long peak_rss_kb = status_number(pid, "VmHWM");
  const long threads_end = status_number(pid, "Threads");
  for (int fd : slow) ::close(fd);
  ::kill(pid, SIGTERM);
  int wstatus = 0;
  ::waitpid(pid, &wstatus, 0);
  nlohmann::json net;
  std::ifstream(out + "/run/network_stats.json") >> net;
  const cslam::Summary st = cslam::summarize(status_ms);
  std::sort(status_ms.begin(), status_ms.end());
  const double p99 =
      status_ms.empty() ? -1 : status_ms[std::min(status_ms.size() - 1, std::size_t(0.99 * double(status_ms.size())))];
  nlohmann::json j = {{"hostile", hostile_on},
                      {"slam", cli.flag_set("slam")},
                      {"good_frames_sent", sender.stats().frames_sent},
                      {"good_all_acked", all_acked},
                      {"good_frames_refused", sender.stats().frames_refused},
                      {"stream_s", stream_s},
                      {"receive_loop_max_ms", net.value("receive_loop_max_ms", -1.0)},
                      {"message_max_ms", net.value("message_max_ms", -1.0)},
                      {"message_max_ms_by_kind", net.value("message_max_ms_by_kind", nlohmann::json::object())},
                      {"receive_loop_max_cpu_ms", net.value("receive_loop_max_cpu_ms", -1.0)},
                      {"message_max_cpu_ms", net.value("message_max_cpu_ms", -1.0)},
                      {"message_max_cpu_ms_by_kind", net.value("message_max_cpu_ms_by_kind", nlohmann::json::object())},
                      {"receive_loops_over_20ms", net.value("receive_loops_over_20ms", 0)},
                      {"decode_max_ms", net.value("decode_max_ms", -1.0)},
                      {"peak_rss_mb", double(peak_rss_kb) / 1024.0},
                      {"threads_idle", threads_idle},
                      {"threads_after_1000_hellos", threads_after_hellos},
                      {"threads_end", threads_end},
                      {"status_probes_ok", status_ms.size()},
                      {"status_probes_failed", status_failed},
                      {"status_ms_p50", st.median},
                      {"status_ms_p99", p99},
                      {"status_ms_max", st.max},
                      {"server_exit", WIFEXITED(wstatus) ? WEXITSTATUS(wstatus) : -1}};
  std::cout << j.dump() << std::endl;
  return 0;
}

}  // namespace

int main(int argc, char** argv) { return cslam::run_main("cslam-bench-hostile", argc, argv, run); }
