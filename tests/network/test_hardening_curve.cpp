// CURVE authentication over loopback: key files, the ZAP handler's counted rejections, keys
// bound to client ids, session ownership by key, and an end-to-end keyed FrameSender.
#include <sys/stat.h>

#include <filesystem>

#include <gtest/gtest.h>

#include "client/frame_sender.h"
#include "core/error.h"
#include "net_test_util.h"
#include "proto/keys/curve_keys.h"
#include "server/http/status_cache.h"

namespace cslam {
namespace {

using test::small_camera;

SystemConfig counting_system() {
  SystemConfig sc;
  sc.run_slam = false;
  return sc;
}

// A DEALER with CURVE keys (empty server key: plain).
class KeyedPeer {
 public:
  KeyedPeer(zmq::context_t& ctx, const std::string& endpoint, const std::string& server_key,
            const auth::CurveKeyPair& own)
      : socket_(ctx, zmq::socket_type::dealer) {
    socket_.set(zmq::sockopt::linger, 0);
    if (!server_key.empty()) {
      socket_.set(zmq::sockopt::curve_serverkey, server_key);
      socket_.set(zmq::sockopt::curve_publickey, own.public_key);
      socket_.set(zmq::sockopt::curve_secretkey, own.secret_key);
    }
    socket_.connect(endpoint);
  }
  void send(const wire::ClientMessage& m) {
    const std::string b = m.SerializeAsString();
    socket_.send(zmq::buffer(b), zmq::send_flags::none);
  }
  std::optional<wire::ServerMessage> receive(int timeout_ms) {
    zmq::pollitem_t item{socket_.handle(), 0, ZMQ_POLLIN, 0};
    zmq::poll(&item, 1, std::chrono::milliseconds(timeout_ms));
    if (!(item.revents & ZMQ_POLLIN)) return std::nullopt;
    zmq::message_t m;
    if (!socket_.recv(m, zmq::recv_flags::dontwait)) return std::nullopt;
    return wire::parse_server_message(m.data(), m.size(), "test");
  }

 private:
  zmq::socket_t socket_;
};

struct Keys {
  std::string dir = test::scratch_dir("curve");
  auth::CurveKeyPair server = auth::generate_keypair();
  auth::CurveKeyPair robot1 = auth::generate_keypair();    // bound to id 1
  auth::CurveKeyPair robot2 = auth::generate_keypair();    // bound to id 2
  auth::CurveKeyPair stranger = auth::generate_keypair();  // not allowed
  Keys() {
    std::filesystem::create_directories(dir + "/allowed");
    auth::write_secret_file(dir + "/server.key", server);
    auth::write_public_file(dir + "/server.pub", server.public_key, {});
    auth::write_public_file(dir + "/allowed/robot1.pub", robot1.public_key, {1});
    auth::write_public_file(dir + "/allowed/robot2.pub", robot2.public_key, {2});
  }
  ~Keys() { std::filesystem::remove_all(dir); }
  server::ReceiverConfig config() const {
    server::ReceiverConfig rc;
    server::CurveConfig c;
    c.server = auth::read_secret_file(dir + "/server.key");
    c.clients = std::make_shared<const auth::KeyRegistry>(auth::read_allowed_dir(dir + "/allowed"));
    rc.curve = c;
    return rc;
  }
};

TEST(Curve, KeyFilesRoundTripAndBadFilesAreClearErrors) {
  Keys k;
  struct stat st {};
  ASSERT_EQ(::stat((k.dir + "/server.key").c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0600u);
  EXPECT_EQ(auth::read_secret_file(k.dir + "/server.key").public_key, k.server.public_key);
  EXPECT_EQ(auth::read_public_file(k.dir + "/server.pub").public_key, k.server.public_key);
  const auto allowed = auth::read_allowed_dir(k.dir + "/allowed");
  ASSERT_EQ(allowed.size(), 2u);
  EXPECT_EQ(allowed[0].client_ids, std::set<ClientId>{1});
  std::ofstream(k.dir + "/bad.pub") << "public-key = short\n";
  EXPECT_THROW(auth::read_public_file(k.dir + "/bad.pub"), ConfigError);
  std::ofstream(k.dir + "/odd.pub") << "publik-key = " << k.server.public_key << "\n";
  EXPECT_THROW(auth::read_public_file(k.dir + "/odd.pub"), ConfigError);
  EXPECT_THROW(auth::read_secret_file(k.dir + "/server.pub"), ConfigError);  // no secret in a .pub
  EXPECT_THROW(auth::parse_client_ids("1,x", "test"), ConfigError);
  EXPECT_THROW(auth::read_allowed_dir(k.dir + "/nowhere"), ConfigError);
}

TEST(Curve, UnauthenticatedPeersGetNothingButACountedRejection) {
  Keys k;
  test::InProcessServer srv(k.config(), counting_system());
  zmq::context_t ctx(1);
  const PinholeCamera cam = small_camera();
  KeyedPeer plain(ctx, srv.endpoint(), "", {});
  KeyedPeer stranger(ctx, srv.endpoint(), k.server.public_key, k.stranger);
  plain.send(test::make_hello(1, cam));
  stranger.send(test::make_hello(1, cam));
  EXPECT_FALSE(plain.receive(1500).has_value());
  EXPECT_FALSE(stranger.receive(1500).has_value());
  // An allowed robot is served meanwhile.
  KeyedPeer robot(ctx, srv.endpoint(), k.server.public_key, k.robot1);
  robot.send(test::make_hello(1, cam));
  const auto w = robot.receive(10000);
  ASSERT_TRUE(w && w->has_welcome());
  std::shared_ptr<const http::NetStatus> s;
  for (int i = 0; i < 500; ++i) {
    s = srv.net_status();
    if (s && s->totals.count("auth_rejected") && s->totals.at("auth_rejected") >= 1 &&
        s->transport.count("handshake_failed"))
      break;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  ASSERT_TRUE(s);
  EXPECT_GE(s->totals.at("auth_rejected"), 1u);  // the stranger's key, refused by ZAP
  EXPECT_GE(s->transport.count("handshake_failed"), 1u) << "transport events: " << http::network_json(*s).dump();
  srv.stop();
  EXPECT_EQ(srv.stats().unattributed().size(), 0u);  // nothing of theirs reached the application
  EXPECT_EQ(srv.sessions().size(), 1u);
}

TEST(Curve, AKeyMaySpeakOnlyForItsIdsAndOwnsItsSession) {
  Keys k;
  test::InProcessServer srv(k.config(), counting_system());
  zmq::context_t ctx(1);
  const PinholeCamera cam = small_camera();
  KeyedPeer robot2(ctx, srv.endpoint(), k.server.public_key, k.robot2);
  robot2.send(test::make_hello(1, cam));  // robot 2's key claims id 1
  auto r = robot2.receive(10000);
  ASSERT_TRUE(r && r->has_error());
  EXPECT_EQ(r->error().code(), wire::ERROR_NOT_AUTHORIZED);

  KeyedPeer robot1(ctx, srv.endpoint(), k.server.public_key, k.robot1);
  robot1.send(test::make_hello(1, cam));
  r = robot1.receive(10000);
  ASSERT_TRUE(r && r->has_welcome());
  robot1.send(test::make_frame(1, 1, 0.0, cam));
  r = robot1.receive(10000);
  ASSERT_TRUE(r && r->has_ack());
  // The same key from a new connection (the robot restarted) takes its session over at once.
  KeyedPeer restarted(ctx, srv.endpoint(), k.server.public_key, k.robot1);
  restarted.send(test::make_hello(1, cam));
  r = restarted.receive(10000);
  ASSERT_TRUE(r && r->has_welcome());
  EXPECT_TRUE(r->welcome().resumed());
  EXPECT_EQ(r->welcome().last_seq(), 1u);
  srv.stop();
  EXPECT_EQ(srv.stats().unattributed().at("not_authorized"), 1u);
}

TEST(Curve, KeyedFrameSenderStreamsEndToEnd) {
  Keys k;
  test::InProcessServer srv(k.config(), counting_system());
  client::SenderConfig cc;
  cc.server = srv.endpoint();
  cc.info.id = 2;
  cc.info.camera = small_camera();
  cc.server_public_key = k.server.public_key;
  cc.public_key = k.robot2.public_key;
  cc.secret_key = k.robot2.secret_key;
  client::FrameSender sender(cc);
  sender.connect();
  RgbdFrame frame;
  frame.bgr = cv::Mat(48, 64, CV_8UC3, cv::Scalar(1, 2, 3));
  frame.depth = cv::Mat(48, 64, CV_16UC1, cv::Scalar(3000));
  for (int i = 0; i < 6; ++i) {
    frame.timestamp = i;
    sender.send_frame(frame);
  }
  EXPECT_TRUE(sender.goodbye(20));
  srv.stop();
  EXPECT_EQ(srv.stats().clients().at(2).frames_accepted, 6u);
}

}  // namespace
}  // namespace cslam
