// godhand-viewer's HTTP + WebSocket server (websocketpp over Boost.Asio, one thread): serves the
// page's files and the scene's meshes over HTTP and the Foxglove WebSocket feed (feed.h) on the
// same port. Every browser-facing rule lives in the Hub; this file only carries bytes.
//
// Threads: publish() and setRoute() may be called from any thread. They never block on a
// client: messages go into a bounded inbox (oldest dropped and counted when the server thread
// falls behind) that the server thread drains into the Hub, which drops per slow client.
#pragma once

#include <atomic>
#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>

#include "viewer/feed.h"

namespace godhand::viewer {

struct ServerError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

struct ServerOptions {
  std::string bind = "127.0.0.1";
  int port = 0;                  ///< 0: a free port
  std::string web_root;          ///< folder with index.html and viewer.js (the built page)
  HubLimits limits;
  std::size_t inbox_capacity = 4096;  ///< messages waiting for the server thread
  /// How long a connection may take from its accept to its handshake's or HTTP response's last
  /// byte sent (websocketpp's open-handshake timeout, its default 5 s): a client that never
  /// reads a response is dropped then, and its HTTP slot (kMaxHttpInFlight) freed.
  long handshake_timeout_ms = 5000;
};

class Server {
 public:
  /// Reads the page files and binds; ServerError (one line) on a bad address, a port in use, a
  /// missing page.
  explicit Server(const ServerOptions& options);
  ~Server();
  Server(const Server&) = delete;
  Server& operator=(const Server&) = delete;

  int port() const { return port_; }
  void start();  ///< the server thread
  void stop();   ///< closes every connection, joins the thread; idempotent

  /// Any thread.
  void publish(std::uint32_t channel, std::string key, std::string payload, std::uint64_t time_ns);
  /// Any thread: an HTTP resource ("/mesh/3/0.bin") served from memory (body shared, not copied).
  void setRoute(const std::string& path, const std::string& content_type, std::shared_ptr<const std::string> body);
  /// Called on the server thread for every valid client publish; must not block.
  void onClientPublish(std::function<void(const ClientPublish&)> handler);
  /// Any thread: forgets a channel's latched payloads (runs in order with publish()).
  void clearLatched(std::uint32_t channel);

  /// The Hub's counters as last copied by the server thread (at most ~0.2 s old), and the inbox's.
  Hub::Stats stats() const;
  std::uint64_t inboxDropped() const { return inbox_dropped_.load(); }
  std::uint64_t httpRequests() const { return http_requests_.load(); }
  std::uint64_t httpNotFound() const { return http_not_found_.load(); }
  /// Network abuse, counted (found by a hostile review): HTTP requests refused while
  /// kMaxHttpInFlight responses were still being sent (clients that never read them held ~4.6 MB
  /// each), pings left unanswered while a client's queue was full (websocketpp queues a pong per
  /// ping, unbounded), WebSocket connections closed because their queue grew past twice the
  /// largest message allowed anyway, handshakes of protocol versions before RFC 6455 (their
  /// reader has no size limit), and handshakes whose Sec-WebSocket-Key is not 16 bytes of base64.
  std::uint64_t httpRefused() const { return http_refused_.load(); }
  std::uint64_t pingsUnanswered() const { return pings_unanswered_.load(); }
  std::uint64_t overflowClosed() const { return overflow_closed_.load(); }
  std::uint64_t oldProtocolRefused() const { return old_protocol_refused_.load(); }
  std::uint64_t badKeyRefused() const { return bad_key_refused_.load(); }
  static constexpr int kMaxHttpInFlight = 16;
  static constexpr int kMaxHttpPerAddress = 8;

  struct Impl;

 private:
  void drain();

  std::unique_ptr<Impl> impl_;
  int port_ = 0;
  std::thread thread_;
  mutable std::mutex mutex_;
  struct Pending {
    std::uint32_t channel;  ///< 0: clear latched of `key`'s channel (see clearLatched)
    std::string key, payload;
    std::uint64_t time_ns;
    bool clear = false;
  };
  std::deque<Pending> inbox_;
  bool drain_posted_ = false;
  std::size_t inbox_capacity_;
  std::map<std::string, std::pair<std::string, std::shared_ptr<const std::string>>> routes_;
  Hub::Stats stats_copy_;
  std::atomic<std::uint64_t> inbox_dropped_{0}, http_requests_{0}, http_not_found_{0};
  std::atomic<std::uint64_t> http_refused_{0}, pings_unanswered_{0}, overflow_closed_{0}, old_protocol_refused_{0},
      bad_key_refused_{0};
  std::atomic<bool> stopped_{false};
};

}  // namespace godhand::viewer
