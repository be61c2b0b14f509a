// The viewer's live feed: the Foxglove WebSocket protocol (subprotocol "foxglove.websocket.v1",
// JSON-encoded channels) between godhand-viewer and any number of browsers, with no network code
// (server.cc carries the bytes). One Hub, used from one thread (the server's):
//
//   server -> client  text   serverInfo, advertise (every channel), status (errors)
//                     binary 0x01 | u32 subscription id | u64 timestamp ns | JSON payload (LE)
//   client -> server  text   subscribe {subscriptions:[{id, channelId}]}, unsubscribe
//                            {subscriptionIds:[..]}, advertise {channels:[{id, topic, encoding}]},
//                            unadvertise {channelIds:[..]}
//                     binary 0x01 | u32 client channel id | payload   (client publish)
//
// Latched channels keep their newest payload per key (one per hand, per service, the one scene):
// a new subscriber gets those at once, so a browser opened late sees the scene and both hands.
//
// Flow control: before each send the Hub asks the client's Sink how many bytes are still queued
// for it; a message that would take that over HubLimits::max_queued_bytes is dropped for that
// client only and counted (Client::dropped). The publisher (the DDS side) is never made to wait.
// Bad client input (not JSON, unknown op, bad fields, unknown channel, wrong opcode) is counted
// (Client::rejected) and answered with one status message; the connection stays open.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

namespace godhand::viewer {

struct Channel {
  std::uint32_t id = 0;
  std::string topic;        ///< "godhand/hand_state", ...
  std::string schema_name;  ///< "godhand.msg.HandState", ...
  bool latched = false;     ///< keep the newest payload per key for new subscribers
};

/// The channels godhand-viewer advertises (ids 1..N, in this order).
std::vector<Channel> viewerChannels();

/// Topic on which a browser may publish synthetic hand targets (client advertise + binary 0x01).
constexpr const char* kSyntheticTargetTopic = "godhand/synthetic_target";

/// Where the bytes of one connection go (server.cc: a websocketpp connection).
class Sink {
 public:
  virtual ~Sink() = default;
  virtual std::size_t buffered() const = 0;  ///< bytes queued for this client, not yet sent
  virtual void sendText(const std::string& text) = 0;
  virtual void sendBinary(const std::string& bytes) = 0;
};

struct HubLimits {
  std::size_t max_queued_bytes = 4u << 20;   ///< per client; beyond: drop and count
  std::size_t max_client_message = 64u << 10;  ///< text or binary from a client
  int max_subscriptions = 64;                ///< per client
  int max_clients = 64;                      ///< more connections are refused
};

/// What a client published on an advertised channel of kSyntheticTargetTopic.
struct ClientPublish {
  int client = 0;
  std::string topic;
  std::string payload;
};

class Hub {
 public:
  struct ClientStats {
    int id = 0;
    std::uint64_t sent = 0, dropped = 0, rejected = 0, sent_bytes = 0;
    int subscriptions = 0;
  };
  struct Stats {
    int clients = 0;                   ///< open now
    std::uint64_t opened = 0, closed = 0, refused = 0;
    std::uint64_t published = 0;       ///< messages handed to publish()
    std::uint64_t sent = 0, dropped = 0, rejected = 0, client_published = 0;  ///< over every client ever
    std::vector<ClientStats> per_client;
  };

  Hub(std::vector<Channel> channels, HubLimits limits, std::string server_name);

  /// A new connection: sends serverInfo and advertise. Returns its id, or 0 when refused
  /// (max_clients): the caller closes it.
  int open(Sink* sink);
  void close(int client);
  /// A text message from a client (subscribe, ...). Bad ones: counted, a status reply.
  void onText(int client, const std::string& text);
  /// A binary message from a client (client publish). Valid ones go to the publish handler.
  void onBinary(int client, const std::string& bytes);
  void onClientPublish(std::function<void(const ClientPublish&)> handler) { client_publish_ = std::move(handler); }

  /// One message on channel `channel` (its id), to every subscriber; latched channels remember it
  /// under `key`. Unknown channel: ignored (programming error, counted in rejected).
  void publish(std::uint32_t channel, const std::string& key, const std::string& payload, std::uint64_t time_ns);
  /// Forgets the latched payloads of a channel (e.g. a new scene replaces the old one).
  void clearLatched(std::uint32_t channel);

  Stats stats() const;
  const std::vector<Channel>& channels() const { return channels_; }
  std::uint32_t channelId(const std::string& topic) const;  ///< 0: none

 private:
  struct Client {
    Sink* sink = nullptr;
    std::map<std::uint32_t, std::uint32_t> subs;        ///< subscription id -> channel id
    std::map<std::uint32_t, std::string> advertised;    ///< client channel id -> topic
    ClientStats stats;
  };
  void reject(Client& c, const std::string& why);
  void deliver(Client& c, std::uint32_t sub, const std::string& payload, std::uint64_t time_ns);

  std::vector<Channel> channels_;
  HubLimits limits_;
  std::string name_;
  std::map<int, Client> clients_;
  std::map<std::uint32_t, std::map<std::string, std::pair<std::string, std::uint64_t>>> latched_;
  std::function<void(const ClientPublish&)> client_publish_;
  int next_id_ = 1;
  Stats totals_;
};

/// 0x01 | u32 LE subscription | u64 LE time | payload.
std::string messageData(std::uint32_t subscription, std::uint64_t time_ns, const std::string& payload);

}  // namespace godhand::viewer
