#include "leap/leap_recording.h"

#include <cmath>
#include <cstdlib>
#include <limits>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>

namespace godhand::leap {
namespace {

using json = nlohmann::json;

enum class VecStatus { kOk, kMissing, kNotFinite };

/// Reads obj[key] as 3 finite numbers. JSON has no NaN: JavaScript writes NaN and Infinity as
/// null, so a null component counts as not finite; an absent key, a null or non-array value, or
/// a wrong length counts as missing.
VecStatus readVec3(const json& obj, const char* key, Vec3* out) {
  const auto it = obj.find(key);
  if (it == obj.end() || !it->is_array() || it->size() != 3) return VecStatus::kMissing;
  for (int k = 0; k < 3; ++k) {
    const json& c = (*it)[static_cast<std::size_t>(k)];
    if (c.is_null()) return VecStatus::kNotFinite;
    if (!c.is_number()) return VecStatus::kMissing;
    (*out)[k] = c.get<double>();
    if (!std::isfinite((*out)[k])) return VecStatus::kNotFinite;
  }
  return VecStatus::kOk;
}

/// Integer value of a JSON number that holds an integer (also 3.0, as JavaScript may write it).
bool readInteger(const json& v, std::int64_t* out) {
  if (v.is_number_integer()) {
    *out = v.get<std::int64_t>();
    return true;
  }
  if (v.is_number_float()) {
    const double d = v.get<double>();
    if (std::isfinite(d) && std::floor(d) == d && std::abs(d) < 9.0e15) {
      *out = static_cast<std::int64_t>(d);
      return true;
    }
  }
  return false;
}

/// leapjs-playback's unPackArray for format 2: a string in the structure names the value at the
/// same index; a nested array means "data is a list, unpack each item with this structure"; an
/// object {key: structure} unpacks the value at that index into a nested object.
json unpack(const json& structure, const json& data) {
  json out = json::object();
  if (!structure.is_array()) return out;
  for (std::size_t i = 0; i < structure.size(); ++i) {
    const json& s = structure[i];
    const json value = data.is_array() && i < data.size() ? data[i] : json();
    if (s.is_string()) {
      out[s.get<std::string>()] = value;
    } else if (s.is_array()) {
      json list = json::array();
      if (data.is_array())
        for (const json& item : data) list.push_back(unpack(s, item));
      return list;
    } else if (s.is_object() && !s.empty()) {
      out[s.begin().key()] = unpack(s.begin().value(), value);
    }
  }
  return out;
}

struct HandCandidate {
  TrackedHand hand;
  bool ok = false;
  HandReject reason = HandReject::kMissingField;
  std::array<int, kFingerCount> finger_count{};
  VecStatus finger_status = VecStatus::kOk;
  bool confidence_defaulted = false;
};

/// Validates one hand entry's own fields (not its fingers) and fills hand (palm frame in W).
bool readHand(const json& h, const Mat3& R_WT, const Vec3& p_WT, HandCandidate* c) {
  auto reject = [&](HandReject r) {
    c->reason = r;
    return false;
  };
  if (!h.is_object()) return reject(HandReject::kNotObject);
  const auto id = h.find("id");
  const auto type = h.find("type");
  if (id == h.end() || id->is_null() || type == h.end() || type->is_null()) return reject(HandReject::kMissingField);
  std::int64_t hid = 0;
  if (!readInteger(*id, &hid) || hid < std::numeric_limits<int>::min() || hid > std::numeric_limits<int>::max()) return reject(HandReject::kBadType);
  c->hand.id = static_cast<int>(hid);
  if (!type->is_string() || (*type != "left" && *type != "right")) return reject(HandReject::kBadType);
  c->hand.right = *type == "right";

  Vec3 pos, normal, dir;
  for (const auto& [key, v] : {std::pair<const char*, Vec3*>{"palmPosition", &pos}, {"palmNormal", &normal}, {"direction", &dir}}) {
    const VecStatus s = readVec3(h, key, v);
    if (s == VecStatus::kMissing) return reject(HandReject::kMissingField);
    if (s == VecStatus::kNotFinite) return reject(HandReject::kNotFinite);
  }
  const auto conf = h.find("confidence");
  if (conf == h.end()) {  // Leap SDK 2.0 recordings carry none: the format's default (tracked, 1)
    c->hand.confidence = Recording::kDefaultConfidence;
    c->confidence_defaulted = true;
  } else if (conf->is_null()) {
    return reject(HandReject::kNotFinite);
  } else if (!conf->is_number()) {
    return reject(HandReject::kMissingField);
  } else {
    c->hand.confidence = conf->get<double>();
  }
  if (!std::isfinite(c->hand.confidence)) return reject(HandReject::kNotFinite);
  if (c->hand.confidence < 0.0 || c->hand.confidence > 1.0) return reject(HandReject::kBadConfidence);

  const double nd = dir.norm(), nn = normal.norm();
  if (std::abs(nd - 1.0) > Recording::kUnitTolerance || std::abs(nn - 1.0) > Recording::kUnitTolerance ||
      std::abs(dir.dot(normal)) / (nd * nn) > Recording::kOrthoTolerance)
    return reject(HandReject::kBadDirection);

  // Palm frame in W: y along the direction, z = −normal made orthogonal to y, x = y × z.
  const Vec3 y = (R_WT * leapDirectionToT(dir)).normalized();
  const Vec3 zn = -(R_WT * leapDirectionToT(normal));
  const Vec3 z = (zn - y * y.dot(zn)).normalized();
  Mat3 R;
  R.col(0) = y.cross(z);
  R.col(1) = y;
  R.col(2) = z;
  c->hand.X_W_palm = {p_WT + R_WT * leapPointToT(pos), Quat(R).normalized()};
  c->ok = true;
  return true;
}

/// Every bone of the hand (palm → mcp, then the phalanges) within [kMinBoneM, kMaxBoneM].
bool plausibleBones(const TrackedHand& h) {
  for (const auto& finger : h.joints_W) {
    Vec3 from = h.X_W_palm.p;
    for (const Vec3& joint : finger) {
      const double len = (joint - from).norm();
      if (!(len >= kMinBoneM && len <= kMaxBoneM)) return false;
      from = joint;
    }
  }
  return true;
}

constexpr const char* kJointKeys[4] = {"mcpPosition", "pipPosition", "dipPosition", "tipPosition"};

/// Assigns the frame's pointables to the candidate hands (by handId and finger type).
void readPointables(const json& pointables, const Mat3& R_WT, const Vec3& p_WT, const std::vector<std::int64_t>& entry_ids,
                    std::vector<HandCandidate>* cands, ReadStats* stats) {
  if (!pointables.is_array()) return;
  for (const json& p : pointables) {
    std::int64_t hand_id = 0;
    const auto hid = p.is_object() ? p.find("handId") : p.end();
    if (!p.is_object() || hid == p.end() || !readInteger(*hid, &hand_id)) {
      ++stats->pointables_ignored;
      continue;
    }
    const auto tool = p.find("tool");
    if (tool != p.end() && tool->is_boolean() && tool->get<bool>()) {
      ++stats->pointables_ignored;
      continue;
    }
    std::int64_t type = -1;
    const auto t = p.find("type");
    if (t != p.end() && !t->is_null()) {
      if (!readInteger(*t, &type)) type = -1;
    } else {  // format 2 packs no type: Leap numbers pointables 10 · hand id + type
      const auto pid = p.find("id");
      std::int64_t id = 0;
      if (pid != p.end() && readInteger(*pid, &id)) type = id - 10 * hand_id;
    }
    if (type < 0 || type >= kFingerCount) {
      ++stats->pointables_ignored;
      continue;
    }
    bool known_hand = false;
    for (std::size_t k = 0; k < cands->size(); ++k) {
      if (entry_ids[k] != hand_id) continue;
      known_hand = true;
      HandCandidate& c = (*cands)[k];
      if (!c.ok) continue;
      ++c.finger_count[static_cast<std::size_t>(type)];
      for (int j = 0; j < 4; ++j) {
        Vec3 v;
        const VecStatus s = readVec3(p, kJointKeys[j], &v);
        if (s != VecStatus::kOk) {
          if (c.finger_status == VecStatus::kOk || s == VecStatus::kMissing) c.finger_status = s;
          continue;
        }
        c.hand.joints_W[static_cast<std::size_t>(type)][static_cast<std::size_t>(j)] = p_WT + R_WT * leapPointToT(v);
      }
    }
    if (!known_hand) ++stats->pointables_ignored;
  }
}

std::string numberText(const json& v) {
  if (v.is_string()) return v.get<std::string>();
  if (v.is_number_integer()) return std::to_string(v.get<std::int64_t>());
  if (v.is_number()) {
    std::ostringstream os;
    os << v.get<double>();
    return os.str();
  }
  return v.dump();
}

}  // namespace

const char* fingerName(int finger) {
  static constexpr const char* kNames[kFingerCount] = {"thumb", "index", "middle", "ring", "pinky"};
  return finger >= 0 && finger < kFingerCount ? kNames[finger] : "?";
}

const char* reasonName(FrameReject r) {
  switch (r) {
    case FrameReject::kNotObject: return "not an object";
    case FrameReject::kMissingTimestamp: return "missing or non-integer timestamp";
    case FrameReject::kDecreasingTimestamp: return "timestamp decreases";
    case FrameReject::kMissingHands: return "missing hands array";
    case FrameReject::kCount: break;
  }
  return "?";
}

const char* reasonName(HandReject r) {
  switch (r) {
    case HandReject::kNotObject: return "not an object";
    case HandReject::kMissingField: return "missing field";
    case HandReject::kBadType: return "bad type or id";
    case HandReject::kNotFinite: return "NaN or infinite value";
    case HandReject::kBadDirection: return "non-unit, degenerate or non-orthogonal direction/normal";
    case HandReject::kBadConfidence: return "confidence outside [0, 1]";
    case HandReject::kDuplicateId: return "duplicate hand id";
    case HandReject::kMissingFinger: return "missing finger";
    case HandReject::kDuplicateFinger: return "duplicate finger";
    case HandReject::kFingerMissingField: return "finger position missing";
    case HandReject::kFingerNotFinite: return "finger position NaN or infinite";
    case HandReject::kDegenerateFinger: return "degenerate finger (a bone under 1 mm or over 0.15 m)";
    case HandReject::kCount: break;
  }
  return "?";
}

std::size_t ReadStats::frames_rejected_total() const {
  std::size_t n = 0;
  for (std::size_t v : frames_rejected) n += v;
  return n;
}

std::size_t ReadStats::hands_rejected_total() const {
  std::size_t n = 0;
  for (std::size_t v : hands_rejected) n += v;
  return n;
}

std::string ReadStats::summary() const {
  std::ostringstream os;
  auto list = [&os](const auto& counts, auto count_enum) {
    bool first = true;
    for (std::size_t i = 0; i < counts.size(); ++i) {
      if (counts[i] == 0) continue;
      os << (first ? "" : ", ") << reasonName(static_cast<decltype(count_enum)>(i)) << " " << counts[i];
      first = false;
    }
    if (first) os << "none";
  };
  os << "frames " << frames_read << "/" << frames_in << " (rejected: ";
  list(frames_rejected, FrameReject::kCount);
  os << "), hands " << hands_read << " (rejected: ";
  list(hands_rejected, HandReject::kCount);
  os << "), pointables ignored " << pointables_ignored;
  if (hands_confidence_defaulted) os << ", hands without confidence (default 1) " << hands_confidence_defaulted;
  return os.str();
}

Recording Recording::load(const std::string& path, const Pose& X_WT) {
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  if (!in) throw RecordingError(path + ": cannot open recording");
  // One copy of the text (a string stream and its str() held two: 2 x 172 MB for a 10-minute
  // recording, beside the JSON document's ~6x).
  const std::streamoff size = in.tellg();
  std::string text(size > 0 ? static_cast<std::size_t>(size) : 0, '\0');
  in.seekg(0);
  if (size > 0) in.read(text.data(), size);
  if (in.bad() || (size > 0 && in.gcount() != size)) throw RecordingError(path + ": read error");
  return fromText(text, path, X_WT);
}

Recording Recording::fromText(const std::string& text, const std::string& source, const Pose& X_WT) {
  auto fail = [&source](const std::string& reason) { return RecordingError(source + ": " + reason); };
  if (!isValidPose(X_WT)) throw fail("tracker pose X_WT is not finite with a unit quaternion");
  json doc;
  try {
    doc = json::parse(text);
  } catch (const json::exception& e) {  // parse_error, and out_of_range for e.g. 1e999
    std::string what = e.what();
    for (char& ch : what)
      if (ch == '\n' || ch == '\r') ch = ' ';
    throw fail("not valid JSON: " + what);
  }
  if (!doc.is_object()) throw fail("expected a JSON object with \"metadata\" and \"frames\"");
  const auto frames_it = doc.find("frames");
  if (frames_it == doc.end() || !frames_it->is_array()) throw fail("no \"frames\" array");
  const json& raw = *frames_it;

  Recording rec;
  const auto meta = doc.find("metadata");
  const json* version = nullptr;
  if (meta != doc.end() && meta->is_object()) {
    const auto v = meta->find("formatVersion");
    if (v != meta->end()) version = &*v;
  }
  bool packed = false;
  if (version == nullptr) {
    packed = !raw.empty() && raw[0].is_array();  // no metadata: recognise the packed layout
    rec.format_ = packed ? "2" : "1";
  } else {
    rec.format_ = numberText(*version);
    const double v = version->is_number() ? version->get<double>() : version->is_string() ? std::atof(rec.format_.c_str()) : -1.0;
    if (v == 2.0) {
      packed = true;
    } else if (v != 0.1 && v != 1.0) {
      throw fail("unsupported formatVersion " + rec.format_ + " (supported: 0.1, 1, 2)");
    }
  }
  if (packed && (raw.empty() || !raw[0].is_array()))
    throw fail("format 2 needs the packing structure as the first frame entry");

  const Mat3 R_WT = X_WT.q.toRotationMatrix();
  const Vec3 p_WT = X_WT.p;
  ReadStats& st = rec.stats_;
  st.frames_in = raw.size() - (packed ? 1 : 0);
  bool have_last = false;
  std::int64_t last_ts = 0;
  for (std::size_t fi = packed ? 1 : 0; fi < raw.size(); ++fi) {
    json unpacked;
    if (packed && raw[fi].is_array()) unpacked = unpack(raw[0], raw[fi]);
    const json& f = packed ? unpacked : raw[fi];
    auto rejectFrame = [&st](FrameReject r) { ++st.frames_rejected[static_cast<std::size_t>(r)]; };
    if (!f.is_object()) {
      rejectFrame(FrameReject::kNotObject);
      continue;
    }
    TrackerFrame frame;
    const auto ts = f.find("timestamp");
    if (ts == f.end() || !readInteger(*ts, &frame.timestamp_us)) {
      rejectFrame(FrameReject::kMissingTimestamp);
      continue;
    }
    const auto hands = f.find("hands");
    if (hands == f.end() || !hands->is_array()) {
      rejectFrame(FrameReject::kMissingHands);
      continue;
    }
    if (have_last && frame.timestamp_us < last_ts) {
      rejectFrame(FrameReject::kDecreasingTimestamp);
      continue;
    }
    const auto fid = f.find("id");
    if (fid == f.end() || !readInteger(*fid, &frame.frame_id)) frame.frame_id = -1;

    std::vector<HandCandidate> cands(hands->size());
    std::vector<std::int64_t> entry_ids(hands->size(), std::numeric_limits<std::int64_t>::min());
    std::map<std::int64_t, int> id_count;
    for (std::size_t k = 0; k < hands->size(); ++k) {
      const json& h = (*hands)[k];
      readHand(h, R_WT, p_WT, &cands[k]);
      if (h.is_object()) {
        const auto id = h.find("id");
        if (id != h.end() && readInteger(*id, &entry_ids[k])) ++id_count[entry_ids[k]];
      }
    }
    for (std::size_t k = 0; k < cands.size(); ++k)
      if (cands[k].ok && id_count[entry_ids[k]] > 1) {
        cands[k].ok = false;
        cands[k].reason = HandReject::kDuplicateId;
      }
    const auto pointables = f.find("pointables");
    if (pointables != f.end()) readPointables(*pointables, R_WT, p_WT, entry_ids, &cands, &st);
    for (HandCandidate& c : cands) {
      if (c.ok) {
        for (int finger = 0; finger < kFingerCount && c.ok; ++finger) {
          const int n = c.finger_count[static_cast<std::size_t>(finger)];
          if (n != 1) {
            c.ok = false;
            c.reason = n == 0 ? HandReject::kMissingFinger : HandReject::kDuplicateFinger;
          }
        }
        if (c.ok && c.finger_status != VecStatus::kOk) {
          c.ok = false;
          c.reason = c.finger_status == VecStatus::kMissing ? HandReject::kFingerMissingField : HandReject::kFingerNotFinite;
        }
        if (c.ok && !plausibleBones(c.hand)) {
          c.ok = false;
          c.reason = HandReject::kDegenerateFinger;
        }
      }
      if (c.ok) {
        frame.hands.push_back(c.hand);
        if (c.confidence_defaulted) ++st.hands_confidence_defaulted;
      } else {
        ++st.hands_rejected[static_cast<std::size_t>(c.reason)];
      }
    }
    st.hands_read += frame.hands.size();
    have_last = true;
    last_ts = frame.timestamp_us;
    rec.frames_.push_back(std::move(frame));
  }
  st.frames_read = rec.frames_.size();
  if (rec.frames_.empty()) {
    if (st.frames_in == 0) throw fail("no frames");
    throw fail("no usable frames (" + st.summary() + ")");
  }
  return rec;
}

double Recording::meanFrameRate() const {
  if (frames_.size() < 2) return 0.0;
  const double dt = static_cast<double>(frames_.back().timestamp_us - frames_.front().timestamp_us) * 1e-6;
  return dt > 0.0 ? static_cast<double>(frames_.size() - 1) / dt : 0.0;
}

Vec3 Recording::meanPalmPosition() const {
  Vec3 sum = Vec3::Zero();
  std::size_t n = 0;
  for (const TrackerFrame& f : frames_)
    for (const TrackedHand& h : f.hands) {
      sum += h.X_W_palm.p;
      ++n;
    }
  return n > 0 ? Vec3(sum / static_cast<double>(n)) : Vec3(Vec3::Zero());
}

}  // namespace godhand::leap
