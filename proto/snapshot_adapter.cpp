#include "proto/snapshot_adapter.h"

#include <chrono>
#include <cmath>
#include <cstring>
#include <fstream>
#include <map>
#include <sstream>

#include <zlib.h>

#include "snapshot.pb.h"

namespace cslam::snapshot {

// The messages snapshot.proto shares with the wire protocol (common.proto, package cslam.wire).
using Pose = wire::Pose;
using Camera = wire::CameraIntrinsics;

namespace {

constexpr char kMagic[8] = {'C', 'S', 'L', 'A', 'M', 'S', 'N', 'P'};
constexpr int kDescriptorBytes = 32;

void put_u32(std::string& out, std::size_t at, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) out[at + i] = char((v >> (8 * i)) & 0xff);
}
void put_u64(std::string& out, std::size_t at, std::uint64_t v) {
  for (int i = 0; i < 8; ++i) out[at + i] = char((v >> (8 * i)) & 0xff);
}
std::uint32_t get_u32(const std::string& in, std::size_t at) {
  std::uint32_t v = 0;
  for (int i = 0; i < 4; ++i) v |= std::uint32_t(std::uint8_t(in[at + i])) << (8 * i);
  return v;
}
std::uint64_t get_u64(const std::string& in, std::size_t at) {
  std::uint64_t v = 0;
  for (int i = 0; i < 8; ++i) v |= std::uint64_t(std::uint8_t(in[at + i])) << (8 * i);
  return v;
}

std::uint32_t crc_of(const char* data, std::size_t size) {
  uLong crc = crc32(0L, Z_NULL, 0);
  while (size > 0) {
    const uInt chunk = uInt(std::min<std::size_t>(size, 1u << 30));
    crc = crc32(crc, reinterpret_cast<const Bytef*>(data), chunk);
    data += chunk;
    size -= chunk;
  }
  return std::uint32_t(crc);
}

// ---- state -> proto ----

void to_proto(const SE3& T, Pose* p) {
  const auto& t = T.translation();
  const auto& q = T.rotation();
  p->set_tx(t.x());
  p->set_ty(t.y());
  p->set_tz(t.z());
  p->set_qx(q.x());
  p->set_qy(q.y());
  p->set_qz(q.z());
  p->set_qw(q.w());
}

void to_proto(const Eigen::Vector3d& v, Vec3* p) {
  p->set_x(v.x());
  p->set_y(v.y());
  p->set_z(v.z());
}

void to_proto(const PinholeCamera& c, Camera* p) {
  p->set_fx(c.fx);
  p->set_fy(c.fy);
  p->set_cx(c.cx);
  p->set_cy(c.cy);
  for (double d : c.dist) p->add_distortion(d);
  p->set_width(std::uint32_t(c.width));
  p->set_height(std::uint32_t(c.height));
  p->set_depth_factor(c.depth_factor);
  p->set_depth_scale_correction(c.depth_scale_correction);
  p->set_name(c.name);
  p->set_readout_time(c.readout_time);
}

struct Encoder {
  Snapshot* snap;
  std::map<const ScalePyramid*, std::uint32_t> pyramids;

  std::uint32_t pyramid_index(const ScalePyramid* p) {
    auto it = pyramids.find(p);
    if (it != pyramids.end()) return it->second;
    Pyramid* out = snap->add_pyramids();
    out->set_num_levels(std::uint32_t(p->num_levels));
    out->set_scale_factor(p->scale_factor);
    for (double s : p->scale) out->add_scale(s);
    for (double s : p->sigma2) out->add_sigma2(s);
    const auto index = std::uint32_t(snap->pyramids_size() - 1);
    pyramids.emplace(p, index);
    return index;
  }

  void frame(const cslam::FrameData& d, Client* client, cslam::snapshot::FrameData* out) {
    const std::size_t n = d.size();
    out->set_frame_seq(d.id.seq);
    out->set_timestamp(d.timestamp);
    std::uint32_t cam = 0;
    for (; cam < std::uint32_t(client->cameras_size()); ++cam) {
      Camera probe;  // compared through the proto form (a client has a handful of cameras)
      to_proto(d.camera, &probe);
      if (probe.SerializeAsString() == client->cameras(int(cam)).SerializeAsString()) break;
    }
    if (cam == std::uint32_t(client->cameras_size())) to_proto(d.camera, client->add_cameras());
    out->set_camera(cam);
    out->set_pyramid(pyramid_index(d.pyramid.get()));
    out->set_num_keypoints(std::uint32_t(n));
    auto* kps = out->mutable_keypoints();
    kps->Resize(int(n * 5), 0.f);
    std::string octaves(n, '\0');
    for (std::size_t i = 0; i < n; ++i) {
      const cv::KeyPoint& k = d.features.keypoints[i];
      float* f = kps->mutable_data() + 5 * i;
      f[0] = k.pt.x;
      f[1] = k.pt.y;
      f[2] = k.size;
      f[3] = k.angle;
      f[4] = k.response;
      octaves[i] = char(std::uint8_t(k.octave));
    }
    out->set_octaves(std::move(octaves));
    std::string desc(n * kDescriptorBytes, '\0');
    if (n) std::memcpy(desc.data(), d.features.descriptors.data(), n * kDescriptorBytes);
    out->set_descriptors(std::move(desc));
    out->mutable_depth()->Add(d.depth.begin(), d.depth.end());
    out->mutable_u_right()->Add(d.u_right.begin(), d.u_right.end());
    auto* und = out->mutable_undistorted();
    und->Reserve(int(2 * n));
    for (const Eigen::Vector2d& u : d.features.undistorted) {
      und->Add(u.x());
      und->Add(u.y());
    }
    std::string colors(n * 3, '\0');
    for (std::size_t i = 0; i < n; ++i)
      for (int c = 0; c < 3; ++c) colors[3 * i + c] = char(d.colors[i][c]);
    out->set_colors(std::move(colors));
    for (double b : d.bounds) out->add_bounds(b);
  }
};

void ref_to_proto(KeyFrameId id, KeyFrameRef* p) {
  p->set_client(id.client);
  p->set_seq(id.seq);
}

// ---- proto -> state (validating) ----

struct Decoder {
  const std::string& source;
  std::vector<std::shared_ptr<const ScalePyramid>> pyramids;

  [[noreturn]] void fail(const std::string& what) const { throw InputError(source, what); }

  static bool finite(double v) { return std::isfinite(v); }

  SE3 pose(const Pose& p, const std::string& what) const {
    const double v[7] = {p.tx(), p.ty(), p.tz(), p.qx(), p.qy(), p.qz(), p.qw()};
    for (double x : v)
      if (!finite(x)) fail(what + ": pose is not finite");
    const Eigen::Quaterniond q(p.qw(), p.qx(), p.qy(), p.qz());
    if (std::abs(q.norm() - 1.0) > 1e-3) fail(what + ": pose rotation is not a unit quaternion");
    return SE3(q, Eigen::Vector3d(p.tx(), p.ty(), p.tz()));
  }

  Eigen::Vector3d vec(const Vec3& v, const std::string& what) const {
    if (!finite(v.x()) || !finite(v.y()) || !finite(v.z())) fail(what + " is not finite");
    return {v.x(), v.y(), v.z()};
  }

  PinholeCamera camera(const Camera& p, const std::string& what) const {
    PinholeCamera c;
    c.fx = p.fx();
    c.fy = p.fy();
    c.cx = p.cx();
    c.cy = p.cy();
    if (p.distortion_size() != 0 && p.distortion_size() != 5) fail(what + ": distortion needs 5 coefficients");
    for (int i = 0; i < p.distortion_size(); ++i) c.dist[std::size_t(i)] = p.distortion(i);
    if (p.width() > 16384 || p.height() > 16384) fail(what + ": image size out of range");
    c.width = int(p.width());
    c.height = int(p.height());
    c.depth_factor = p.depth_factor();
    c.depth_scale_correction = p.depth_scale_correction();
    c.name = p.name();
    c.readout_time = p.readout_time();
    try {
      c.validate();
    } catch (const std::exception& e) {
      fail(what + ": " + e.what());
    }
    return c;
  }

  void read_pyramids(const Snapshot& s) {
    for (int i = 0; i < s.pyramids_size(); ++i) {
      const Pyramid& p = s.pyramids(i);
      const std::string what = "pyramid " + std::to_string(i);
      if (p.num_levels() < 1 || p.num_levels() > 32) fail(what + ": level count out of range");
      if (!(p.scale_factor() > 1.0 && p.scale_factor() < 4.0)) fail(what + ": scale factor out of range");
      if (p.scale_size() != int(p.num_levels()) || p.sigma2_size() != int(p.num_levels()))
        fail(what + ": per-level arrays do not match the level count");
      auto out = std::make_shared<ScalePyramid>();
      out->num_levels = int(p.num_levels());
      out->scale_factor = p.scale_factor();
      out->log_scale_factor = std::log(p.scale_factor());
      for (int l = 0; l < p.scale_size(); ++l) {
        if (!(p.scale(l) > 0 && finite(p.scale(l))) || !(p.sigma2(l) > 0 && finite(p.sigma2(l))))
          fail(what + ": non-positive scale");
        out->scale.push_back(p.scale(l));
        out->sigma2.push_back(p.sigma2(l));
        out->inv_sigma2.push_back(1.0 / p.sigma2(l));
      }
      pyramids.push_back(std::move(out));
    }
  }

  std::shared_ptr<const cslam::FrameData> frame(const cslam::snapshot::FrameData& p, ClientId client,
                                                const std::vector<PinholeCamera>& cameras,
                                                const cslam::RgbdParams& rgbd, const std::string& what) const {
    const std::size_t n = p.num_keypoints();
    if (n > 100000) fail(what + ": keypoint count out of range");
    if (std::size_t(p.keypoints_size()) != 5 * n || p.octaves().size() != n ||
        p.descriptors().size() != n * kDescriptorBytes || std::size_t(p.depth_size()) != n ||
        std::size_t(p.u_right_size()) != n || p.colors().size() != 3 * n || p.bounds_size() != 4 ||
        (p.undistorted_size() != 0 && std::size_t(p.undistorted_size()) != 2 * n))
      fail(what + ": per-keypoint arrays do not match the keypoint count");
    if (p.camera() >= cameras.size()) fail(what + ": unknown camera");
    if (p.pyramid() >= pyramids.size()) fail(what + ": unknown pyramid");
    auto d = std::make_shared<cslam::FrameData>();
    d->id = {client, p.frame_seq()};
    if (!finite(p.timestamp())) fail(what + ": timestamp is not finite");
    d->timestamp = p.timestamp();
    d->camera = cameras[p.camera()];
    d->rgbd = rgbd;
    d->pyramid = pyramids[p.pyramid()];
    d->features.keypoints.resize(n);
    d->features.undistorted.resize(n);
    d->features.descriptors.resize(n);
    for (std::size_t i = 0; i < n; ++i) {
      const float* f = p.keypoints().data() + 5 * i;
      for (int k = 0; k < 5; ++k)
        if (!std::isfinite(f[k])) fail(what + ": keypoint is not finite");
      const int octave = std::uint8_t(p.octaves()[i]);
      if (octave >= d->pyramid->num_levels) fail(what + ": keypoint level out of range");
      d->features.keypoints[i] = cv::KeyPoint(f[0], f[1], f[2], f[3], f[4], octave);
      d->features.undistorted[i] = Eigen::Vector2d(f[0], f[1]);
    }
    if (p.undistorted_size() != 0) {
      for (std::size_t i = 0; i < n; ++i) {
        d->features.undistorted[i] = Eigen::Vector2d(p.undistorted(int(2 * i)), p.undistorted(int(2 * i + 1)));
        if (!d->features.undistorted[i].allFinite()) fail(what + ": undistorted keypoint is not finite");
      }
    } else if (d->camera.has_distortion()) {
      d->camera.undistort_pixels(d->features.undistorted);  // as OrbExtractor::extract computes them
    }
    if (n) std::memcpy(d->features.descriptors.data(), p.descriptors().data(), n * kDescriptorBytes);
    d->depth.assign(p.depth().begin(), p.depth().end());
    d->u_right.assign(p.u_right().begin(), p.u_right().end());
    for (std::size_t i = 0; i < n; ++i)
      if (!std::isfinite(d->depth[i]) || !std::isfinite(d->u_right[i])) fail(what + ": depth is not finite");
    d->colors.resize(n);
    for (std::size_t i = 0; i < n; ++i)
      d->colors[i] = cv::Vec3b(std::uint8_t(p.colors()[3 * i]), std::uint8_t(p.colors()[3 * i + 1]),
                               std::uint8_t(p.colors()[3 * i + 2]));
    for (int i = 0; i < 4; ++i) {
      if (!finite(p.bounds(i))) fail(what + ": image bounds are not finite");
      d->bounds[std::size_t(i)] = p.bounds(i);
    }
    if (!(d->bounds[1] > d->bounds[0]) || !(d->bounds[3] > d->bounds[2]) || d->bounds[1] - d->bounds[0] > 1e5 ||
        d->bounds[3] - d->bounds[2] > 1e5)
      fail(what + ": image bounds are empty or out of range");
    derive_frame_data(*d, nullptr, 0);  // grid; BoW comes with the vocabulary at restore
    return d;
  }

  MapState map(const cslam::snapshot::Map& p, ClientId client, const std::vector<PinholeCamera>& cameras,
               const cslam::RgbdParams& rgbd) const {
    MapState m;
    m.client = client;
    m.index = int(p.index());
    m.group = p.group();
    const std::string where = "client " + std::to_string(client) + " map " + std::to_string(p.index());
    if (p.has_origin()) m.origin = KeyFrameId{client, p.origin()};
    auto ref = [&](const KeyFrameRef& r) {
      if (r.client() != client) fail(where + ": link to another client's keyframe");
      return KeyFrameId{client, r.seq()};
    };
    m.keyframes.reserve(std::size_t(p.keyframes_size()));
    for (const auto& k : p.keyframes()) {
      KeyFrameState s;
      s.id = {client, k.seq()};
      const std::string what = where + " keyframe " + std::to_string(k.seq());
      s.data = frame(k.data(), client, cameras, rgbd, what);
      s.T_cam_world = pose(k.t_cam_world(), what);
      if (k.has_parent()) s.parent = ref(k.parent());
      for (const auto& c : k.connections()) {
        if (c.weight() < 0) fail(what + ": negative covisibility weight");
        s.connections.emplace_back(ref(c.keyframe()), c.weight());
      }
      for (const auto& l : k.loop_edges()) s.loop_edges.push_back(ref(l));
      s.first_connection = k.first_connection();
      if (k.has_creation_reference()) {
        s.creation_reference = ref(k.creation_reference());
        s.T_cam_creation_ref = pose(k.t_cam_creation_ref(), what);
      }
      m.keyframes.push_back(std::move(s));
    }
    m.points.reserve(std::size_t(p.points_size()));
    for (const auto& q : p.points()) {
      MapPointState s;
      s.id = {client, q.seq()};
      const std::string what = where + " point " + std::to_string(q.seq());
      s.position = vec(q.position(), what + " position");
      s.normal = vec(q.normal(), what + " normal");
      if (q.orb_descriptor().size() != kDescriptorBytes) fail(what + ": descriptor is not 32 bytes");
      std::memcpy(s.descriptor.data(), q.orb_descriptor().data(), kDescriptorBytes);
      if (!finite(q.min_distance()) || !finite(q.max_distance())) fail(what + ": distances are not finite");
      s.min_distance = q.min_distance();
      s.max_distance = q.max_distance();
      if (q.obs_keyframe_size() != q.obs_index_size()) fail(what + ": observation arrays differ in length");
      for (int i = 0; i < q.obs_keyframe_size(); ++i) {
        if (q.obs_index(i) > 100000) fail(what + ": observation index out of range");
        s.observations.emplace_back(KeyFrameId{client, q.obs_keyframe(i)}, int(q.obs_index(i)));
      }
      bool ref_observed = false;
      for (const auto& [id, idx] : s.observations) ref_observed |= id.seq == q.reference();
      if (!ref_observed) fail(what + ": reference keyframe does not observe it");
      s.reference = KeyFrameId{client, q.reference()};
      s.visible = q.visible();
      s.found = q.found();
      s.color = cv::Vec3b(std::uint8_t(q.color() & 0xff), std::uint8_t((q.color() >> 8) & 0xff),
                          std::uint8_t((q.color() >> 16) & 0xff));
      s.first_keyframe_seq = q.first_keyframe_seq();
      m.points.push_back(std::move(s));
    }
    return m;
  }
};

}  // namespace

namespace {

void to_proto(MapKey k, MapRef* p) {
  p->set_client(k.client);
  p->set_index(std::uint32_t(k.index));
}

void fusion_to_proto(const FusionState& f, Snapshot* snap) {
  for (const SeamState& s : f.seams) {
    Seam* q = snap->add_seams();
    to_proto(s.kept_map, q->mutable_kept_map());
    to_proto(s.moved_map, q->mutable_moved_map());
    for (const auto& [kept, moved] : s.links) {
      q->add_kept_points(kept.seq);
      q->add_moved_points(moved.seq);
    }
    for (const SeamEdgeState& e : s.edges) {
      q->add_edge_kept_keyframes(e.kept.seq);
      q->add_edge_moved_keyframes(e.moved.seq);
      q->add_edge_weights(e.weight);
    }
  }
  for (const MapLinkState& l : f.last_links) {
    MapLink* q = snap->add_map_links();
    to_proto(l.query, q->mutable_query());
    to_proto(l.other, q->mutable_other());
    q->set_query_keyframes_at_link(l.query_keyframes_at_link);
  }
  for (const ConsistencyState& c : f.consistency) {
    Consistency* q = snap->add_consistency();
    to_proto(c.query, q->mutable_query());
    to_proto(c.other, q->mutable_other());
    for (const auto& [members, count] : c.groups) {
      ConsistentGroup* g = q->add_groups();
      for (KeyFrameId id : members) g->add_members(id.seq);
      g->set_count(count);
    }
  }
  for (const auto& [map, n] : f.keyframes_seen) {
    KeyframesSeen* q = snap->add_keyframes_seen();
    to_proto(map, q->mutable_map());
    q->set_keyframes(n);
  }
}

// The maps they name are checked when the state is restored (FusionManager::restore_state).
FusionState fusion_from_proto(const Snapshot& snap, const std::string& source) {
  auto key = [&](const MapRef& r) {
    if (r.client() > 0xffff || r.index() > 0x7fffffff)
      throw InputError(source, "map fusion names a map out of range (client " + std::to_string(r.client()) + ")");
    return MapKey{ClientId(r.client()), int(r.index())};
  };
  FusionState f;
  for (const Seam& q : snap.seams()) {
    if (q.kept_points_size() != q.moved_points_size() ||
        q.edge_kept_keyframes_size() != q.edge_moved_keyframes_size() ||
        q.edge_kept_keyframes_size() != q.edge_weights_size())
      throw InputError(source, "a fusion seam's point or edge lists differ in length");
    SeamState s;
    s.kept_map = key(q.kept_map());
    s.moved_map = key(q.moved_map());
    for (int i = 0; i < q.kept_points_size(); ++i)
      s.links.emplace_back(MapPointId{s.kept_map.client, q.kept_points(i)},
                           MapPointId{s.moved_map.client, q.moved_points(i)});
    for (int i = 0; i < q.edge_weights_size(); ++i)
      s.edges.push_back({KeyFrameId{s.kept_map.client, q.edge_kept_keyframes(i)},
                         KeyFrameId{s.moved_map.client, q.edge_moved_keyframes(i)}, q.edge_weights(i)});
    f.seams.push_back(std::move(s));
  }
  for (const MapLink& q : snap.map_links())
    f.last_links.push_back({key(q.query()), key(q.other()), q.query_keyframes_at_link()});
  for (const Consistency& q : snap.consistency()) {
    ConsistencyState c{key(q.query()), key(q.other()), {}};
    for (const ConsistentGroup& g : q.groups()) {
      std::vector<KeyFrameId> members;
      for (std::uint32_t seq : g.members()) members.push_back(KeyFrameId{c.other.client, seq});
      c.groups.emplace_back(std::move(members), g.count());
    }
    f.consistency.push_back(std::move(c));
  }
  for (const KeyframesSeen& q : snap.keyframes_seen()) f.keyframes_seen.emplace_back(key(q.map()), q.keyframes());
  return f;
}

}  // namespace

std::string encode(const SystemState& state, const EncodeOptions& options) {
  Snapshot snap;
  Header* h = snap.mutable_header();
  h->set_format("cslam-snapshot");
  h->set_version(kFormatVersion);
  h->set_producer(options.producer);
  h->set_created_unix_s(std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count());
  h->set_vocabulary_words(options.vocabulary_words);
  Encoder enc{&snap, {}};
  for (const ClientSlamState& cs : state.clients) {
    Client* c = snap.add_clients();
    c->set_id(cs.info.id);
    c->set_name(cs.info.name);
    to_proto(cs.info.camera, c->mutable_camera());
    c->set_last_seq(cs.last_seq);
    c->set_last_timestamp(cs.last_timestamp);
    c->set_current_map(std::uint32_t(cs.current_map));
    c->set_next_keyframe(cs.next_ids[0]);
    c->set_next_map_point(cs.next_ids[1]);
    c->set_next_frame(cs.next_ids[2]);
    c->set_frames_processed(cs.frames_processed);
    c->set_frames_tracked(cs.frames_tracked);
    c->set_frames_lost(cs.frames_lost);
    c->set_frames_rejected(cs.frames_rejected);
    cslam::RgbdParams rgbd;
    for (const MapState& ms : cs.maps)
      if (!ms.keyframes.empty()) rgbd = ms.keyframes.front().data->rgbd;
    c->mutable_rgbd()->set_bf(rgbd.bf);
    c->mutable_rgbd()->set_th_depth(rgbd.th_depth);
    c->mutable_rgbd()->set_min_depth(rgbd.min_depth);
    c->mutable_rgbd()->set_max_depth(rgbd.max_depth);
    for (const MapState& ms : cs.maps) {
      cslam::snapshot::Map* m = c->add_maps();
      m->set_index(std::uint32_t(ms.index));
      m->set_group(ms.group);
      m->set_has_origin(ms.origin.has_value());
      if (ms.origin) m->set_origin(ms.origin->seq);
      for (const KeyFrameState& ks : ms.keyframes) {
        cslam::snapshot::KeyFrame* k = m->add_keyframes();
        k->set_seq(ks.id.seq);
        enc.frame(*ks.data, c, k->mutable_data());
        to_proto(ks.T_cam_world, k->mutable_t_cam_world());
        if (ks.parent) ref_to_proto(*ks.parent, k->mutable_parent());
        for (const auto& [id, w] : ks.connections) {
          Connection* con = k->add_connections();
          ref_to_proto(id, con->mutable_keyframe());
          con->set_weight(w);
        }
        for (KeyFrameId l : ks.loop_edges) ref_to_proto(l, k->add_loop_edges());
        k->set_first_connection(ks.first_connection);
        if (ks.creation_reference) {
          ref_to_proto(*ks.creation_reference, k->mutable_creation_reference());
          to_proto(ks.T_cam_creation_ref, k->mutable_t_cam_creation_ref());
        }
      }
      for (const MapPointState& ps : ms.points) {
        cslam::snapshot::MapPoint* q = m->add_points();
        q->set_seq(ps.id.seq);
        to_proto(ps.position, q->mutable_position());
        to_proto(ps.normal, q->mutable_normal());
        q->set_orb_descriptor(std::string(reinterpret_cast<const char*>(ps.descriptor.data()), kDescriptorBytes));
        q->set_min_distance(ps.min_distance);
        q->set_max_distance(ps.max_distance);
        for (const auto& [id, idx] : ps.observations) {
          q->add_obs_keyframe(id.seq);
          q->add_obs_index(std::uint32_t(idx));
        }
        q->set_reference(ps.reference ? ps.reference->seq : ps.observations.front().first.seq);
        q->set_visible(ps.visible);
        q->set_found(ps.found);
        q->set_color(std::uint32_t(ps.color[0]) | (std::uint32_t(ps.color[1]) << 8) |
                     (std::uint32_t(ps.color[2]) << 16));
        q->set_first_keyframe_seq(ps.first_keyframe_seq);
      }
    }
    for (const FrameRecordState& r : cs.records) {
      FrameRecord* fr = c->add_records();
      fr->set_timestamp(r.timestamp);
      fr->set_map(std::uint32_t(r.map_index));
      fr->set_reference(r.reference.seq);
      to_proto(r.T_cam_ref, fr->mutable_t_cam_ref());
    }
  }
  fusion_to_proto(state.fusion, &snap);
  std::string out(kHeaderBytes, '\0');
  if (!snap.AppendToString(&out)) throw std::runtime_error("snapshot: serialisation failed");
  std::memcpy(out.data(), kMagic, sizeof kMagic);
  put_u32(out, 8, kFormatVersion);
  put_u32(out, 12, 0);  // flags
  put_u64(out, 16, out.size() - kHeaderBytes);
  put_u32(out, 24, crc_of(out.data() + kHeaderBytes, out.size() - kHeaderBytes));
  put_u32(out, 28, 0);  // reserved
  return out;
}

SystemState decode(const std::string& bytes, const std::string& source, FileInfo* info) {
  auto fail = [&](const std::string& what) { throw InputError(source, what); };
  if (bytes.size() < sizeof kMagic || std::memcmp(bytes.data(), kMagic, sizeof kMagic) != 0)
    fail(bytes.size() < sizeof kMagic ? "not a cslam snapshot (" + std::to_string(bytes.size()) + " bytes, no header)"
                                      : "not a cslam snapshot (no CSLAMSNP magic at the start)");
  if (bytes.size() < kHeaderBytes)
    fail("truncated: " + std::to_string(bytes.size()) + " bytes, shorter than the " + std::to_string(kHeaderBytes) +
         "-byte header");
  const std::uint32_t version = get_u32(bytes, 8);
  if (version != kFormatVersion)
    fail("snapshot format version " + std::to_string(version) + " is not supported (this build reads version " +
         std::to_string(kFormatVersion) + ")");
  if (get_u32(bytes, 12) != 0 || get_u32(bytes, 28) != 0)
    fail("unknown header flags " + std::to_string(get_u32(bytes, 12)) + "/" + std::to_string(get_u32(bytes, 28)));
  const std::uint64_t length = get_u64(bytes, 16);
  const std::uint64_t have = bytes.size() - kHeaderBytes;
  if (length > have)
    fail("truncated: header announces " + std::to_string(length) + " payload bytes, file has " + std::to_string(have));
  if (length < have) fail(std::to_string(have - length) + " unexpected bytes after the payload");
  const std::uint32_t stored = get_u32(bytes, 24), computed = crc_of(bytes.data() + kHeaderBytes, length);
  if (stored != computed) {
    std::ostringstream os;
    os << "checksum mismatch (stored 0x" << std::hex << stored << ", content 0x" << computed
       << "): the file is corrupt";
    fail(os.str());
  }
  Snapshot snap;
  if (!snap.ParseFromArray(bytes.data() + kHeaderBytes, int(length))) fail("payload is not a valid snapshot message");
  if (snap.header().format() != "cslam-snapshot" || snap.header().version() != version)
    fail("payload header does not describe a cslam snapshot of version " + std::to_string(version));
  if (info) {
    info->version = version;
    info->payload_bytes = length;
    info->crc32 = stored;
    info->producer = snap.header().producer();
    info->created_unix_s = snap.header().created_unix_s();
    info->vocabulary_words = snap.header().vocabulary_words();
  }
  Decoder dec{source, {}};
  dec.read_pyramids(snap);
  SystemState state;
  std::map<ClientId, bool> seen;
  for (const Client& c : snap.clients()) {
    if (c.id() > 0xffff) fail("client id " + std::to_string(c.id()) + " out of range");
    ClientSlamState cs;
    cs.info.id = ClientId(c.id());
    if (!seen.emplace(cs.info.id, true).second) fail("client " + std::to_string(c.id()) + " appears twice");
    const std::string where = "client " + std::to_string(c.id());
    cs.info.name = c.name();
    cs.info.camera = dec.camera(c.camera(), where + " camera");
    std::vector<PinholeCamera> cameras;
    for (int i = 0; i < c.cameras_size(); ++i)
      cameras.push_back(dec.camera(c.cameras(i), where + " camera " + std::to_string(i)));
    cs.last_seq = c.last_seq();
    if (!std::isfinite(c.last_timestamp())) fail(where + ": last timestamp is not finite");
    cs.last_timestamp = c.last_timestamp();
    cs.current_map = int(c.current_map());
    cs.next_ids = {c.next_keyframe(), c.next_map_point(), c.next_frame()};
    cs.frames_processed = c.frames_processed();
    cs.frames_tracked = c.frames_tracked();
    cs.frames_lost = c.frames_lost();
    cs.frames_rejected = c.frames_rejected();
    if (c.maps_size() == 0) fail(where + ": no map");
    if (c.current_map() >= std::uint32_t(c.maps_size())) fail(where + ": current map out of range");
    cslam::RgbdParams rgbd;
    rgbd.bf = c.rgbd().bf();
    rgbd.th_depth = c.rgbd().th_depth();
    rgbd.min_depth = c.rgbd().min_depth();
    rgbd.max_depth = c.rgbd().max_depth();
    if (!(rgbd.bf > 0) || !std::isfinite(rgbd.bf) || !std::isfinite(rgbd.th_depth) || !std::isfinite(rgbd.min_depth) ||
        !std::isfinite(rgbd.max_depth))
      fail(where + ": RGB-D parameters out of range");
    for (int i = 0; i < c.maps_size(); ++i) {
      if (c.maps(i).index() != std::uint32_t(i)) fail(where + ": maps are not numbered 0..n-1");
      cs.maps.push_back(dec.map(c.maps(i), cs.info.id, cameras, rgbd));
    }
    for (const FrameRecord& r : c.records()) {
      if (r.map() >= std::uint32_t(c.maps_size())) fail(where + ": frame record in an unknown map");
      if (!std::isfinite(r.timestamp())) fail(where + ": frame record time is not finite");
      cs.records.push_back({r.timestamp(), int(r.map()), KeyFrameId{cs.info.id, r.reference()},
                            dec.pose(r.t_cam_ref(), where + " frame record")});
    }
    state.clients.push_back(std::move(cs));
  }
  state.fusion = fusion_from_proto(snap, source);
  return state;
}

SystemState read_file(const std::string& path, FileInfo* info) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, "cannot open snapshot file");
  std::ostringstream ss;
  ss << in.rdbuf();
  if (in.bad()) throw InputError(path, "read error");
  return decode(ss.str(), path, info);
}

}  // namespace cslam::snapshot
