// Local-map file I/O; see map_io.hpp.
#include "slam/map/map_io.hpp"

#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iterator>
#include <vector>

namespace rgbdquad::slam {

namespace {

constexpr char kMagic[8] = {'R', 'G', 'B', 'D', 'Q', 'M', 'A', 'P'};
// Sanity bounds: far above what a flight makes, far below what a corrupt count would claim.
constexpr std::uint64_t kMaxKeyframes = 100000;
constexpr std::uint64_t kMaxFeaturesPerKeyframe = 100000;
constexpr std::uint64_t kMaxPoints = 50000000;
constexpr std::uint64_t kMaxObservations = 100000;
constexpr int kThumbnailCols = 40, kThumbnailRows = 30;

std::uint64_t fnv1a(const std::vector<std::uint8_t>& bytes, std::size_t n) {
  return fnv1a64(bytes.data(), n);
}

class Writer {
 public:
  template <typename T>
  void put(T v) {
    static_assert(std::is_arithmetic_v<T>, "arithmetic only");
    std::uint8_t b[sizeof(T)];
    std::memcpy(b, &v, sizeof(T));  // host is little-endian (checked in save_map)
    bytes_.insert(bytes_.end(), b, b + sizeof(T));
  }
  void raw(const void* p, std::size_t n) {
    const auto* c = static_cast<const std::uint8_t*>(p);
    bytes_.insert(bytes_.end(), c, c + n);
  }
  void pose(const Eigen::Isometry3d& T) {
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 4; ++c) put<double>(T.matrix()(r, c));
  }
  std::vector<std::uint8_t>& bytes() { return bytes_; }

 private:
  std::vector<std::uint8_t> bytes_;
};

class Reader {
 public:
  Reader(const std::vector<std::uint8_t>& b, std::size_t end) : b_(b), end_(end) {}
  template <typename T>
  bool get(T* v) {
    if (end_ - pos_ < sizeof(T)) return false;
    std::memcpy(v, b_.data() + pos_, sizeof(T));
    pos_ += sizeof(T);
    return true;
  }
  bool raw(void* p, std::size_t n) {
    if (end_ - pos_ < n) return false;
    std::memcpy(p, b_.data() + pos_, n);
    pos_ += n;
    return true;
  }
  bool pose(Eigen::Isometry3d* T) {
    Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 4; ++c)
        if (!get(&m(r, c))) return false;
    if (!m.allFinite()) return false;
    T->matrix() = m;
    return true;
  }
  std::size_t left() const { return end_ - pos_; }

 private:
  const std::vector<std::uint8_t>& b_;
  std::size_t end_;
  std::size_t pos_ = 0;
};

std::uint8_t kind_code(DetectorKind k) {
  switch (k) {
    case DetectorKind::kSift:
      return 0;
    case DetectorKind::kSurf:
      return 1;
    case DetectorKind::kOrb:
      return 2;
  }
  return 255;
}

bool fail(std::string* error, const std::string& path, const std::string& why) {
  if (error) *error = "map file '" + path + "': " + why;
  return false;
}

}  // namespace

std::uint64_t fnv1a64(const std::uint8_t* data, std::size_t n) {
  std::uint64_t h = 1469598103934665603ull;
  for (std::size_t i = 0; i < n; ++i) {
    h ^= data[i];
    h *= 1099511628211ull;
  }
  return h;
}

namespace {

/// The map points with their observations. Depthless keypoints are not saved
/// (FrameFeatures::depthless), nor their observations; a point seen only by them goes with them.
void write_points(const SlamMap& map, std::size_t descriptor_bytes, Writer* out) {
  Writer& w = *out;
  const auto saved_observations = [&](const MapPoint& p) {
    std::vector<std::pair<std::int64_t, int>> kept;
    for (const auto& [kf, kp] : p.observations)
      if (const MapKeyframe* k = map.keyframe(kf); k && !k->is_depthless(kp))
        kept.emplace_back(kf, kp);
    return kept;
  };
  std::size_t saved_points = 0;
  for (const auto& [id, p] : map.points()) saved_points += saved_observations(p).empty() ? 0 : 1;
  w.put<std::uint64_t>(saved_points);
  for (const auto& [id, p] : map.points()) {
    const auto observations = saved_observations(p);
    if (observations.empty()) continue;
    w.put<std::int64_t>(p.id);
    for (int a = 0; a < 3; ++a) w.put<double>(p.p_world_m[a]);
    w.raw(p.descriptor.ptr(), descriptor_bytes);
    w.put<std::int64_t>(p.first_keyframe);
    w.put<std::int64_t>(p.first_keyframe_serial);
    w.put<std::int32_t>(p.visible);
    w.put<std::int32_t>(p.found);
    w.put<std::uint64_t>(observations.size());
    for (const auto& [kf, kp] : observations) {
      w.put<std::int64_t>(kf);
      w.put<std::int32_t>(kp);
    }
  }
}

}  // namespace

bool save_map(const std::string& path, const SlamMap& map, const MapFileContext& ctx,
              std::string* error, std::uint64_t map_corrections) {
  const std::uint16_t probe = 1;
  if (*reinterpret_cast<const std::uint8_t*>(&probe) != 1)
    return fail(error, path, "this host is big-endian; the format is little-endian");
  Writer w;
  w.raw(kMagic, sizeof kMagic);
  w.put<std::uint32_t>(kMapFileVersion);
  const CameraModel& c = ctx.camera;
  for (double v : {c.fx_px, c.fy_px, c.cx_px, c.cy_px, c.bf_px_m}) w.put<double>(v);
  w.put<std::int32_t>(c.width_px);
  w.put<std::int32_t>(c.height_px);
  w.put<std::uint8_t>(kind_code(ctx.features.kind));
  int cols = 0, type = -1;
  for (const auto& [id, kf] : map.keyframes()) {
    const cv::Mat& d = kf.features.features->descriptors;
    if (d.rows > 0) {
      cols = d.cols;
      type = d.type();
      break;
    }
  }
  w.put<std::int32_t>(cols);
  w.put<std::int32_t>(type);
  const std::size_t elem = type == CV_32F ? 4 : 1;
  w.put<std::uint64_t>(map.keyframes().size());
  for (const auto& [id, kf] : map.keyframes()) {
    const FrameFeatures& f = *kf.features.features;
    w.put<std::int64_t>(kf.id);
    w.put<double>(kf.stamp_s);
    w.pose(kf.T_world_cam);
    w.put<std::uint64_t>(f.keypoints.size());
    for (std::size_t i = 0; i < f.keypoints.size(); ++i) {
      const cv::KeyPoint& k = f.keypoints[i];
      for (float v : {k.pt.x, k.pt.y, k.size, k.angle, k.response}) w.put<float>(v);
      w.put<std::int32_t>(k.octave);
      for (int a = 0; a < 3; ++a) w.put<double>(f.points_cam_m[i][a]);
      const cv::Vec3b col = i < f.colours_bgr.size() ? f.colours_bgr[i] : cv::Vec3b(0, 0, 0);
      w.raw(&col[0], 3);
      w.raw(f.descriptors.ptr(static_cast<int>(i)), static_cast<std::size_t>(cols) * elem);
      w.put<std::int64_t>(kf.point_ids[i]);
    }
    const bool thumb = kf.thumbnail.rows == kThumbnailRows && kf.thumbnail.cols == kThumbnailCols &&
                       kf.thumbnail.type() == CV_32F && kf.thumbnail.isContinuous();
    w.put<std::uint8_t>(thumb ? 1 : 0);
    if (thumb) w.raw(kf.thumbnail.ptr(), kThumbnailCols * kThumbnailRows * sizeof(float));
  }
  write_points(map, static_cast<std::size_t>(cols) * elem, &w);
  w.put<std::uint64_t>(map.culled().size());
  for (const auto& [id, c2] : map.culled()) {
    w.put<std::int64_t>(id);
    w.put<std::int64_t>(c2.parent);
    w.pose(c2.T_parent_kf);
  }
  w.put<std::uint64_t>(map.loop_edges().size());
  for (const LoopEdge& e : map.loop_edges()) {
    w.put<std::int64_t>(e.a);
    w.put<std::int64_t>(e.b);
    w.pose(e.T_a_b);
  }
  w.put<std::uint64_t>(map_corrections);
  w.put<std::uint64_t>(fnv1a(w.bytes(), w.bytes().size()));
  const std::string tmp = path + ".tmp";
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) return fail(error, path, "cannot write " + tmp);
    out.write(reinterpret_cast<const char*>(w.bytes().data()),
              static_cast<std::streamsize>(w.bytes().size()));
    out.flush();
    if (!out) return fail(error, path, "write failed");
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0) return fail(error, path, "cannot rename " + tmp);
  return true;
}

namespace {
/// The file's bytes when its magic, version and checksum are right; nullopt with `error` else.
std::optional<std::vector<std::uint8_t>> read_verified(const std::string& path,
                                                       std::string* error) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    fail(error, path, "cannot open");
    return std::nullopt;
  }
  std::vector<std::uint8_t> b((std::istreambuf_iterator<char>(in)),
                              std::istreambuf_iterator<char>());
  if (b.size() < sizeof kMagic + 4 + 8 || std::memcmp(b.data(), kMagic, sizeof kMagic) != 0) {
    fail(error, path, "not an rgbdquad map file (bad magic)");
    return std::nullopt;
  }
  std::uint32_t version = 0;
  std::memcpy(&version, b.data() + sizeof kMagic, 4);
  if (version != kMapFileVersion) {
    fail(error, path,
         "format version " + std::to_string(version) + ", this build reads version " +
             std::to_string(kMapFileVersion));
    return std::nullopt;
  }
  std::uint64_t stored = 0;
  std::memcpy(&stored, b.data() + b.size() - 8, 8);
  if (fnv1a(b, b.size() - 8) != stored) {
    fail(error, path, "checksum mismatch (corrupt or truncated file)");
    return std::nullopt;
  }
  return b;
}
}  // namespace

bool check_map_file(const std::string& path, std::string* error) {
  return read_verified(path, error).has_value();
}

namespace {

/// Reads the sections of a verified map file in order; each step returns false with `error` set
/// (the file's path and what is wrong) on the first inconsistency.
class MapFileParser {
 public:
  MapFileParser(const std::vector<std::uint8_t>& bytes, const std::string& path,
                const MapFileContext& ctx, std::string* error)
      : r_(bytes, bytes.size() - 8), path_(path), ctx_(ctx), error_(error) {}

  /// Magic and version (checked by read_verified), then the camera, image size and detector the
  /// map was made with: they must be this run's.
  bool header() {
    char magic[8];
    std::uint32_t version;
    r_.raw(magic, 8);
    r_.get(&version);
    double cam[5];
    std::int32_t w = 0, h = 0;
    std::uint8_t kind = 0;
    for (double& x : cam)
      if (!r_.get(&x)) return corrupt("camera");
    if (!r_.get(&w) || !r_.get(&h) || !r_.get(&kind) || !r_.get(&cols_) || !r_.get(&type_))
      return corrupt("header");
    const CameraModel& c = ctx_.camera;
    const double expect[5] = {c.fx_px, c.fy_px, c.cx_px, c.cy_px, c.bf_px_m};
    for (int i = 0; i < 5; ++i)
      if (!(std::abs(cam[i] - expect[i]) <= 1e-6))
        return fail(error_, path_,
                    "made with another camera (fx " + std::to_string(cam[0]) + " fy " +
                        std::to_string(cam[1]) + " cx " + std::to_string(cam[2]) + " cy " +
                        std::to_string(cam[3]) + "; this run has fx " + std::to_string(c.fx_px) +
                        " fy " + std::to_string(c.fy_px) + " cx " + std::to_string(c.cx_px) +
                        " cy " + std::to_string(c.cy_px) + ")");
    if (w != c.width_px || h != c.height_px)
      return fail(error_, path_,
                  "made for " + std::to_string(w) + "x" + std::to_string(h) + " images");
    if (kind != kind_code(ctx_.features.kind))
      return fail(error_, path_,
                  "made with another feature detector (code " + std::to_string(kind) +
                      ", this run uses " + to_string(ctx_.features.kind) + ")");
    if (cols_ < 0 || cols_ > 1024 || (type_ != CV_8U && type_ != CV_32F && cols_ > 0))
      return corrupt("descriptor shape");
    desc_bytes_ = static_cast<std::size_t>(cols_) * (type_ == CV_32F ? 4 : 1);
    return true;
  }

  bool keyframes(std::map<std::int64_t, MapKeyframe>* kfs) {
    std::uint64_t nkf = 0;
    if (!r_.get(&nkf) || nkf > kMaxKeyframes) return corrupt("keyframe count");
    for (std::uint64_t i = 0; i < nkf; ++i) {
      MapKeyframe kf;
      if (!keyframe(&kf)) return false;
      const std::int64_t id = kf.id;
      (*kfs)[id] = std::move(kf);
    }
    return true;
  }

  bool points(const std::map<std::int64_t, MapKeyframe>& kfs,
              std::map<std::int64_t, MapPoint>* pts) {
    std::uint64_t np = 0;
    if (!r_.get(&np) || np > kMaxPoints) return corrupt("point count");
    for (std::uint64_t i = 0; i < np; ++i) {
      MapPoint p;
      if (!point(kfs, &p)) return false;
      const std::int64_t id = p.id;
      (*pts)[id] = std::move(p);
    }
    // Every keypoint's point must exist (and see it back).
    for (const auto& [id, kf] : kfs)
      for (std::size_t k = 0; k < kf.point_ids.size(); ++k) {
        const std::int64_t pid = kf.point_ids[k];
        if (pid < 0) continue;
        auto it = pts->find(pid);
        if (it == pts->end() || !it->second.observations.count(id))
          return corrupt("keypoint refers to a missing point");
      }
    return true;
  }

  bool culled(std::map<std::int64_t, CulledKeyframe>* culled) {
    std::uint64_t nc = 0;
    if (!r_.get(&nc) || nc > kMaxKeyframes) return corrupt("culled count");
    for (std::uint64_t i = 0; i < nc; ++i) {
      std::int64_t id;
      CulledKeyframe ck;
      if (!r_.get(&id) || !r_.get(&ck.parent) || !r_.pose(&ck.T_parent_kf))
        return corrupt("culled keyframe");
      (*culled)[id] = ck;
    }
    return true;
  }

  bool loop_edges(const std::map<std::int64_t, MapKeyframe>& kfs, std::vector<LoopEdge>* loops) {
    std::uint64_t nl = 0;
    if (!r_.get(&nl) || nl > kMaxKeyframes) return corrupt("loop edge count");
    for (std::uint64_t i = 0; i < nl; ++i) {
      LoopEdge e;
      if (!r_.get(&e.a) || !r_.get(&e.b) || !r_.pose(&e.T_a_b)) return corrupt("loop edge");
      if (!kfs.count(e.a) || !kfs.count(e.b)) return corrupt("loop edge between unknown keyframes");
      loops->push_back(e);
    }
    return true;
  }

  /// The map's count of loop corrections, which ends the file.
  bool trailer(std::uint64_t* corrections) {
    if (!r_.get(corrections)) return corrupt("map corrections");
    if (r_.left() != 0) return corrupt("trailing bytes");
    return true;
  }

 private:
  bool corrupt(const char* what) {
    return fail(error_, path_, std::string("malformed content (") + what + ")");
  }

  bool keyframe(MapKeyframe* kf) {
    std::uint64_t nf = 0;
    if (!r_.get(&kf->id) || !r_.get(&kf->stamp_s) || !r_.pose(&kf->T_world_cam) || !r_.get(&nf) ||
        nf > kMaxFeaturesPerKeyframe)
      return corrupt("keyframe");
    auto f = std::make_shared<FrameFeatures>();
    f->descriptors.create(static_cast<int>(nf), cols_, type_ == CV_32F ? CV_32F : CV_8U);
    kf->point_ids.resize(nf);
    for (std::uint64_t k = 0; k < nf; ++k) {
      float x, y, size, angle, response;
      std::int32_t octave;
      Eigen::Vector3d p;
      cv::Vec3b col;
      if (!r_.get(&x) || !r_.get(&y) || !r_.get(&size) || !r_.get(&angle) || !r_.get(&response) ||
          !r_.get(&octave) || !r_.get(&p[0]) || !r_.get(&p[1]) || !r_.get(&p[2]) ||
          !r_.raw(&col[0], 3) || !r_.raw(f->descriptors.ptr(static_cast<int>(k)), desc_bytes_) ||
          !r_.get(&kf->point_ids[k]))
        return corrupt("keypoint");
      if (!p.allFinite() || !(p.z() > 0)) return corrupt("keypoint depth");
      f->keypoints.emplace_back(cv::Point2f(x, y), size, angle, response, octave);
      f->points_cam_m.push_back(p);
      f->colours_bgr.push_back(col);
    }
    f->detected = nf;
    kf->features = TrackedFeatures::from(f, ctx_.camera, ctx_.features);
    std::uint8_t thumb = 0;
    if (!r_.get(&thumb)) return corrupt("thumbnail flag");
    if (thumb) {
      kf->thumbnail.create(kThumbnailRows, kThumbnailCols, CV_32F);
      if (!r_.raw(kf->thumbnail.ptr(), kThumbnailCols * kThumbnailRows * sizeof(float)))
        return corrupt("thumbnail");
    }
    return true;
  }

  bool point(const std::map<std::int64_t, MapKeyframe>& kfs, MapPoint* p) {
    std::uint64_t nobs = 0;
    p->descriptor.create(1, cols_, type_ == CV_32F ? CV_32F : CV_8U);
    if (!r_.get(&p->id) || !r_.get(&p->p_world_m[0]) || !r_.get(&p->p_world_m[1]) ||
        !r_.get(&p->p_world_m[2]) || !r_.raw(p->descriptor.ptr(), desc_bytes_) ||
        !r_.get(&p->first_keyframe) || !r_.get(&p->first_keyframe_serial) || !r_.get(&p->visible) ||
        !r_.get(&p->found) || !r_.get(&nobs) || nobs > kMaxObservations)
      return corrupt("point");
    if (!p->p_world_m.allFinite()) return corrupt("point position");
    for (std::uint64_t o = 0; o < nobs; ++o) {
      std::int64_t kf;
      std::int32_t kp;
      if (!r_.get(&kf) || !r_.get(&kp)) return corrupt("observation");
      auto it = kfs.find(kf);
      if (it == kfs.end() || kp < 0 ||
          static_cast<std::size_t>(kp) >= it->second.point_ids.size() ||
          it->second.point_ids[static_cast<std::size_t>(kp)] != p->id)
        return corrupt("observation does not match its keyframe");
      p->observations[kf] = kp;
    }
    return true;
  }

  Reader r_;
  const std::string& path_;
  const MapFileContext& ctx_;
  std::string* error_;
  std::int32_t cols_ = 0, type_ = 0;
  std::size_t desc_bytes_ = 0;
};

}  // namespace

std::optional<SlamMap> load_map(const std::string& path, const MapFileContext& ctx,
                                std::string* error, std::uint64_t* map_corrections) {
  const auto bytes = read_verified(path, error);
  if (!bytes) return std::nullopt;
  MapFileParser parse(*bytes, path, ctx, error);
  std::map<std::int64_t, MapKeyframe> kfs;
  std::map<std::int64_t, MapPoint> pts;
  std::map<std::int64_t, CulledKeyframe> culled;
  std::vector<LoopEdge> loops;
  std::uint64_t corrections = 0;
  if (!parse.header() || !parse.keyframes(&kfs) || !parse.points(kfs, &pts) ||
      !parse.culled(&culled) || !parse.loop_edges(kfs, &loops) || !parse.trailer(&corrections))
    return std::nullopt;
  SlamMap map;
  map.restore(std::move(kfs), std::move(pts), std::move(culled), std::move(loops));
  if (map_corrections) *map_corrections = corrections;
  return map;
}

}  // namespace rgbdquad::slam
