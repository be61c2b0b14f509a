#include "viewer/feed.h"

#include <algorithm>

#include <nlohmann/json.hpp>

namespace godhand::viewer {

using nlohmann::json;

std::vector<Channel> viewerChannels() {
  return {
      {1, "godhand/hand_state", "godhand.msg.HandState", true},
      {2, "godhand/hand_target", "godhand.msg.HandTarget", true},
      {3, "godhand/scene_description", "godhand.msg.SceneDescription", true},
      {4, "godhand/scene_state", "godhand.msg.SceneState", true},
      {5, "godhand/contact_forces", "godhand.msg.ContactForces", false},
      {6, "godhand/service_status", "godhand.msg.ServiceStatus", true},
      {7, "godhand/viewer_stats", "godhand.viewer.Stats", true},
  };
}

std::string messageData(std::uint32_t subscription, std::uint64_t time_ns, const std::string& payload) {
  std::string out;
  out.reserve(13 + payload.size());
  out.push_back('\x01');
  for (int i = 0; i < 4; ++i) out.push_back(static_cast<char>((subscription >> (8 * i)) & 0xffu));
  for (int i = 0; i < 8; ++i) out.push_back(static_cast<char>((time_ns >> (8 * i)) & 0xffu));
  out += payload;
  return out;
}

Hub::Hub(std::vector<Channel> channels, HubLimits limits, std::string server_name)
    : channels_(std::move(channels)), limits_(limits), name_(std::move(server_name)) {}

std::uint32_t Hub::channelId(const std::string& topic) const {
  for (const Channel& c : channels_)
    if (c.topic == topic) return c.id;
  return 0;
}

int Hub::open(Sink* sink) {
  if (static_cast<int>(clients_.size()) >= limits_.max_clients) {
    ++totals_.refused;
    return 0;
  }
  const int id = next_id_++;
  Client& c = clients_[id];
  c.sink = sink;
  c.stats.id = id;
  ++totals_.opened;
  sink->sendText(json{{"op", "serverInfo"},
                      {"name", name_},
                      {"capabilities", json::array({"clientPublish"})},
                      {"supportedEncodings", json::array({"json"})},
                      {"metadata", json::object()},
                      {"sessionId", std::to_string(id)}}
                     .dump());
  json chans = json::array();
  for (const Channel& ch : channels_)
    chans.push_back({{"id", ch.id},
                     {"topic", ch.topic},
                     {"encoding", "json"},
                     {"schemaName", ch.schema_name},
                     {"schema", "{\"type\":\"object\"}"},
                     {"schemaEncoding", "jsonschema"}});
  sink->sendText(json{{"op", "advertise"}, {"channels", chans}}.dump());
  return id;
}

void Hub::close(int client) {
  auto it = clients_.find(client);
  if (it == clients_.end()) return;
  ++totals_.closed;
  totals_.sent += it->second.stats.sent;
  totals_.dropped += it->second.stats.dropped + it->second.waiting.size();  // never sent
  totals_.superseded += it->second.stats.superseded;
  totals_.rejected += it->second.stats.rejected;
  clients_.erase(it);
}

void Hub::reject(Client& c, const std::string& why) {
  ++c.stats.rejected;
  // One status message per rejection, but never more than the flow control allows.
  const std::string text = json{{"op", "status"}, {"level", 2}, {"message", why}}.dump();
  // (At the flow-control mark, not the hard cap: each reply is a message of its own to the
  // transport, and 64 clients sending bad messages without reading held 6-22 MB each.)
  if (c.sink->buffered() + text.size() <= limits_.send_below_bytes) c.sink->sendText(text);
}

bool Hub::sendable(const Client& c, std::size_t size) const {
  if (c.stats.acks && c.stats.sent - c.stats.acked >= limits_.max_unacked) return false;
  const std::size_t queued = c.sink->buffered();
  return queued + size <= limits_.send_below_bytes || (queued == 0 && size <= limits_.max_queued_bytes);
}

void Hub::send(Client& c, std::uint32_t sub, const std::string& payload, std::uint64_t time_ns) {
  const std::size_t size = 13 + payload.size();
  c.sink->sendBinary(messageData(sub, time_ns, payload));
  ++c.stats.sent;
  c.stats.sent_bytes += size;
}

void Hub::flush(Client& c) {
  std::size_t done = 0;
  while (done < c.waiting.size() && sendable(c, 13 + c.waiting[done].payload.size())) {
    const Waiting& w = c.waiting[done];
    send(c, w.sub, w.payload, w.time_ns);
    ++done;
  }
  if (done > 0) c.waiting.erase(c.waiting.begin(), c.waiting.begin() + static_cast<std::ptrdiff_t>(done));
}

void Hub::flush() {
  for (auto& [id, c] : clients_) flush(c);
}

void Hub::deliver(Client& c, std::uint32_t sub, const std::string& key, const std::string& payload, std::uint64_t time_ns) {
  const std::size_t size = 13 + payload.size();
  if (size > limits_.max_queued_bytes) {  // could never be sent
    ++c.stats.dropped;
    return;
  }
  flush(c);  // older waiting messages go first
  if (c.waiting.empty() && sendable(c, size)) return send(c, sub, payload, time_ns);
  for (Waiting& w : c.waiting) {
    if (w.sub != sub || w.key != key) continue;
    w.payload = payload;  // the newer one takes the older one's place in line
    w.time_ns = time_ns;
    ++c.stats.dropped;
    ++c.stats.superseded;
    return;
  }
  c.waiting.push_back(Waiting{sub, key, payload, time_ns});
}

namespace {
// A non-negative integer that fits u32, else nullptr-like failure.
bool u32(const json& j, const char* key, std::uint32_t* out) {
  auto it = j.find(key);
  if (it == j.end() || !it->is_number_integer()) return false;
  const auto v = it->get<long long>();
  if (v < 0 || v > 0xffffffffLL) return false;
  *out = static_cast<std::uint32_t>(v);
  return true;
}
}  // namespace

void Hub::onText(int client, const std::string& text) {
  auto it = clients_.find(client);
  if (it == clients_.end()) return;
  Client& c = it->second;
  if (text.size() > limits_.max_client_message) return reject(c, "message too large");
  json j = json::parse(text, nullptr, false);
  if (j.is_discarded() || !j.is_object()) return reject(c, "not a JSON object");
  auto op = j.find("op");
  if (op == j.end() || !op->is_string()) return reject(c, "no \"op\"");
  const std::string o = op->get<std::string>();
  if (o == "subscribe") {
    auto subs = j.find("subscriptions");
    if (subs == j.end() || !subs->is_array()) return reject(c, "subscribe: no \"subscriptions\" array");
    for (const json& s : *subs) {
      std::uint32_t sid = 0, cid = 0;
      if (!s.is_object() || !u32(s, "id", &sid) || !u32(s, "channelId", &cid))
        return reject(c, "subscribe: each subscription needs integer \"id\" and \"channelId\"");
      const Channel* ch = nullptr;
      for (const Channel& x : channels_)
        if (x.id == cid) ch = &x;
      if (!ch) return reject(c, "subscribe: unknown channel " + std::to_string(cid));
      if (c.subs.count(sid)) return reject(c, "subscribe: subscription id " + std::to_string(sid) + " in use");
      if (static_cast<int>(c.subs.size()) >= limits_.max_subscriptions) return reject(c, "subscribe: too many subscriptions");
      c.subs[sid] = cid;
      c.stats.subscriptions = static_cast<int>(c.subs.size());
      if (ch->latched) {
        auto l = latched_.find(cid);
        if (l != latched_.end())
          for (const auto& [key, m] : l->second) deliver(c, sid, key, m.first, m.second);
      }
    }
  } else if (o == "unsubscribe") {
    auto ids = j.find("subscriptionIds");
    if (ids == j.end() || !ids->is_array()) return reject(c, "unsubscribe: no \"subscriptionIds\" array");
    for (const json& s : *ids) {
      if (!s.is_number_integer()) return reject(c, "unsubscribe: ids must be integers");
      const long long v = s.get<long long>();
      if (v < 0 || v > 0xffffffffLL || !c.subs.erase(static_cast<std::uint32_t>(v)))
        return reject(c, "unsubscribe: no subscription " + s.dump());
      // What waited for it is no longer wanted (not a loss: the client asked to stop).
      const std::uint32_t sub = static_cast<std::uint32_t>(v);
      c.waiting.erase(std::remove_if(c.waiting.begin(), c.waiting.end(), [sub](const Waiting& w) { return w.sub == sub; }),
                      c.waiting.end());
        }
    c.stats.subscriptions = static_cast<int>(c.subs.size());
  } else if (o == "ack") {
    auto n = j.find("received");
    if (n == j.end() || !n->is_number_unsigned()) return reject(c, "ack: \"received\" must be a non-negative integer");
    const std::uint64_t v = n->get<std::uint64_t>();
    if (v < c.stats.acked || v > c.stats.sent)
      return reject(c, "ack: received " + std::to_string(v) + " outside [" + std::to_string(c.stats.acked) + ", " +
                           std::to_string(c.stats.sent) + "] (the last ack, the messages sent)");
    c.stats.acks = true;
    c.stats.acked = v;
    flush(c);
  } else if (o == "advertise") {
    auto chans = j.find("channels");
    if (chans == j.end() || !chans->is_array()) return reject(c, "advertise: no \"channels\" array");
    for (const json& ch : *chans) {
      std::uint32_t id = 0;
      if (!ch.is_object() || !u32(ch, "id", &id) || !ch.contains("topic") || !ch["topic"].is_string())
        return reject(c, "advertise: each channel needs integer \"id\" and string \"topic\"");
      const std::string topic = ch["topic"].get<std::string>();
      if (topic != kSyntheticTargetTopic) return reject(c, "advertise: clients may publish only on " + std::string(kSyntheticTargetTopic));
      if (!ch.contains("encoding") || ch["encoding"] != "json") return reject(c, "advertise: encoding must be \"json\"");
      if (c.advertised.size() >= 16 && !c.advertised.count(id)) return reject(c, "advertise: too many channels");
      c.advertised[id] = topic;
    }
  } else if (o == "unadvertise") {
    auto ids = j.find("channelIds");
    if (ids == j.end() || !ids->is_array()) return reject(c, "unadvertise: no \"channelIds\" array");
    for (const json& s : *ids) {
      if (!s.is_number_integer() || s.get<long long>() < 0 || s.get<long long>() > 0xffffffffLL)
        return reject(c, "unadvertise: ids must be integers");
      c.advertised.erase(static_cast<std::uint32_t>(s.get<long long>()));
    }
  } else {
    return reject(c, "unknown op \"" + o.substr(0, 32) + "\"");
  }
}

void Hub::onBinary(int client, const std::string& bytes) {
  auto it = clients_.find(client);
  if (it == clients_.end()) return;
  Client& c = it->second;
  if (bytes.size() > limits_.max_client_message) return reject(c, "message too large");
  if (bytes.size() < 5) return reject(c, "binary message shorter than 5 bytes");
  if (static_cast<unsigned char>(bytes[0]) != 0x01) return reject(c, "unknown binary opcode");
  std::uint32_t id = 0;
  for (int i = 0; i < 4; ++i) id |= static_cast<std::uint32_t>(static_cast<unsigned char>(bytes[1 + i])) << (8 * i);
  auto ch = c.advertised.find(id);
  if (ch == c.advertised.end()) return reject(c, "client publish on channel " + std::to_string(id) + " never advertised");
  ++totals_.client_published;
  if (client_publish_) client_publish_(ClientPublish{client, ch->second, bytes.substr(5)});
}

void Hub::publish(std::uint32_t channel, const std::string& key, const std::string& payload, std::uint64_t time_ns) {
  const Channel* ch = nullptr;
  for (const Channel& x : channels_)
    if (x.id == channel) ch = &x;
  if (!ch) {
    ++totals_.rejected;
    return;
  }
  ++totals_.published;
  if (ch->latched) latched_[channel][key] = {payload, time_ns};
  for (auto& [id, c] : clients_)
    for (const auto& [sid, cid] : c.subs)
      if (cid == channel) deliver(c, sid, key, payload, time_ns);
}

void Hub::clearLatched(std::uint32_t channel) { latched_.erase(channel); }

Hub::Stats Hub::stats() const {
  Stats s = totals_;
  s.clients = static_cast<int>(clients_.size());
  for (const auto& [id, c] : clients_) {
    s.sent += c.stats.sent;
    s.dropped += c.stats.dropped;
    s.superseded += c.stats.superseded;
    s.rejected += c.stats.rejected;
    s.per_client.push_back(c.stats);
    s.per_client.back().waiting = static_cast<int>(c.waiting.size());  // derived here, not kept twice
  }
  return s;
}

}  // namespace godhand::viewer
