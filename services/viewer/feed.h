// The viewer's live feed: the Foxglove WebSocket protocol (subprotocol "foxglove.websocket.v1",
// JSON-encoded channels) between godhand-viewer and any number of browsers, with no network code
// (server.cc carries the bytes). One Hub, used from one thread (the server's):
//
//   server -> client  text   serverInfo, advertise (every channel), status (errors)
//                     binary 0x01 | u32 subscription id | u64 timestamp ns | JSON payload (LE)
//   client -> server  text   subscribe {subscriptions:[{id, channelId}]}, unsubscribe
//                            {subscriptionIds:[..]}, advertise {channels:[{id, topic, encoding}]},
//                            unadvertise {channelIds:[..]}, and godhand's own
//                            ack {received: N}: N binary messages handled so far (see below)
//                     binary 0x01 | u32 client channel id | payload   (client publish)
//
// Latched channels keep their newest payload per key (one per hand, per service, the one scene):
// a new subscriber gets those at once, so a browser opened late sees the scene and both hands.
//
// Flow control, per client (the publisher, the DDS side, is never made to wait): a message is
// sent at once while the bytes still queued for the client (its Sink's buffered()) stay below
// HubLimits::send_below_bytes. Otherwise it waits, one per channel and key: a newer message of the
// same channel and key supersedes the waiting one (counted as dropped and superseded), and the
// waiting ones go out, oldest first, as the queue drains (flush(), which the server calls on a
// timer). So a slow browser gets the newest state of every hand after a bounded delay, never a
// backlog of stale ones, and a large message (a HandState with its contacts) cannot be starved by
// small ones that still fit. A message larger than max_queued_bytes is dropped and counted.
// The server's queue is not the only one: the kernel's socket buffers and the browser's own event
// queue can hold seconds of messages for a page whose script is starved of CPU (measured: a page
// drawing states 22 s old under two busy loops). A client that acks (our page does, each time it
// has handled a few messages) is also held to HubLimits::max_unacked messages sent and not yet
// handled: beyond, messages wait as above. Clients that never ack (other Foxglove clients) are
// held to the byte rule only.
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
  std::size_t max_queued_bytes = 4u << 20;   ///< per client: a message larger than this is dropped, counted
  std::size_t send_below_bytes = 256u << 10;  ///< per client: queued beyond this, messages wait (see above)
  std::uint64_t max_unacked = 128;             ///< per acking client: sent, not yet handled; beyond, messages wait
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
    std::uint64_t superseded = 0;  ///< of dropped: replaced while waiting by a newer one (same channel, key)
    int subscriptions = 0;
    int waiting = 0;               ///< messages waiting now (one per channel and key at most)
    std::uint64_t acked = 0;       ///< binary messages the client said it handled (acking clients)
    bool acks = false;             ///< the client acks (flow control by handled messages too)
  };
  struct Stats {
    int clients = 0;                   ///< open now
    std::uint64_t opened = 0, closed = 0, refused = 0;
    std::uint64_t published = 0;       ///< messages handed to publish()
    std::uint64_t sent = 0, dropped = 0, rejected = 0, client_published = 0;  ///< over every client ever
    std::uint64_t superseded = 0;      ///< of dropped (over every client ever)
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
  /// Sends waiting messages to every client whose queue has drained below send_below_bytes.
  void flush();

  Stats stats() const;
  const std::vector<Channel>& channels() const { return channels_; }
  std::uint32_t channelId(const std::string& topic) const;  ///< 0: none

 private:
  struct Waiting {
    std::uint32_t sub = 0;
    std::string key, payload;
    std::uint64_t time_ns = 0;
  };
  struct Client {
    Sink* sink = nullptr;
    std::vector<Waiting> waiting;                       ///< oldest first; one per (sub, key)
    std::map<std::uint32_t, std::uint32_t> subs;        ///< subscription id -> channel id
    std::map<std::uint32_t, std::string> advertised;    ///< client channel id -> topic
    ClientStats stats;
  };
  void reject(Client& c, const std::string& why);
  void deliver(Client& c, std::uint32_t sub, const std::string& key, const std::string& payload, std::uint64_t time_ns);
  bool sendable(const Client& c, std::size_t size) const;
  void send(Client& c, std::uint32_t sub, const std::string& payload, std::uint64_t time_ns);
  void flush(Client& c);

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
