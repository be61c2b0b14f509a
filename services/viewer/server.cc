#include "viewer/server.h"

#include <algorithm>
#include <fstream>
#include <set>
#include <sstream>
#include <vector>

#include <websocketpp/config/asio_no_tls.hpp>
#include <websocketpp/server.hpp>

namespace godhand::viewer {

namespace {
using WsServer = websocketpp::server<websocketpp::config::asio>;
using Hdl = websocketpp::connection_hdl;
constexpr const char* kSubprotocol = "foxglove.websocket.v1";

class ConnSink : public Sink {
 public:
  explicit ConnSink(WsServer::connection_ptr c) : con_(std::move(c)) {}
  std::size_t buffered() const override { return con_->get_buffered_amount(); }
  void sendText(const std::string& text) override { con_->send(text, websocketpp::frame::opcode::text); }
  void sendBinary(const std::string& bytes) override { con_->send(bytes, websocketpp::frame::opcode::binary); }

 private:
  WsServer::connection_ptr con_;
};

/// RFC 6455 4.1: the key is 16 bytes in base64, i.e. 22 base64 characters and "==".
bool validWebSocketKey(const std::string& k) {
  if (k.size() != 24 || k.compare(22, 2, "==") != 0) return false;
  for (std::size_t i = 0; i < 22; ++i) {
    const char c = k[i];
    if (!((c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '+' || c == '/')) return false;
  }
  // The 22nd character carries 2 bits of data and 4 of padding: one of A, Q, g, w.
  return std::string("AQgw").find(k[21]) != std::string::npos;
}

std::string readFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return {};
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}
}  // namespace

struct Server::Impl {
  WsServer ws;
  std::unique_ptr<Hub> hub;
  std::map<Hdl, std::pair<int, std::unique_ptr<ConnSink>>, std::owner_less<Hdl>> conns;
  /// HTTP connections answered and not yet gone (weak handles), with the client's address.
  std::vector<std::pair<Hdl, std::string>> http_in_flight;
  std::size_t overflow_bytes = 0;   ///< a WebSocket queue beyond this is closed (twice the largest message)
  std::size_t pong_below_bytes = 0; ///< a ping is answered while the queue is below this
  std::unique_ptr<boost::asio::steady_timer> stats_timer;
};

Server::Server(const ServerOptions& o) : impl_(std::make_unique<Impl>()), inbox_capacity_(o.inbox_capacity) {
  impl_->hub = std::make_unique<Hub>(viewerChannels(), o.limits, "godhand-viewer");
  for (const char* f : {"index.html", "viewer.js"}) {
    std::string body = readFile(o.web_root + "/" + f);
    if (body.empty())
      throw ServerError(o.web_root + "/" + f + ": missing (build the page: npm ci and npm run build in services/viewer/web)");
    routes_[std::string("/") + f] = {std::string(f).find(".js") != std::string::npos ? "text/javascript" : "text/html; charset=utf-8",
                                     std::make_shared<const std::string>(std::move(body))};
  }
  std::string map = readFile(o.web_root + "/viewer.js.map");
  if (!map.empty()) routes_["/viewer.js.map"] = {"application/json", std::make_shared<const std::string>(std::move(map))};
  routes_["/"] = routes_["/index.html"];

  WsServer& ws = impl_->ws;
  ws.clear_access_channels(websocketpp::log::alevel::all);
  ws.clear_error_channels(websocketpp::log::elevel::all);
  websocketpp::lib::error_code ec;
  ws.init_asio(ec);
  if (ec) throw ServerError("cannot start the server: " + ec.message());
  ws.set_reuse_addr(true);
  ws.set_max_message_size(o.limits.max_client_message);
  ws.set_max_http_body_size(o.limits.max_client_message);
  ws.set_listen_backlog(64);
  if (o.handshake_timeout_ms < 1) throw ServerError("handshake timeout must be at least 1 ms");
  ws.set_open_handshake_timeout(o.handshake_timeout_ms);

  impl_->overflow_bytes = 2 * o.limits.max_queued_bytes;
  impl_->pong_below_bytes = o.limits.send_below_bytes;
  ws.set_validate_handler([this](Hdl h) {
    auto con = impl_->ws.get_con_from_hdl(h);
    // Only RFC 6455 (version 13): websocketpp's reader of the older drafts (hybi-00 / hixie-76)
    // has no message size limit, so a client that never ends a message grew the viewer without bound.
    if (con->get_request_header("Sec-WebSocket-Version") != "13") {
      ++old_protocol_refused_;
      return false;
    }
    // A key that is not 16 bytes of base64 is not a WebSocket client (RFC 6455 4.2.1: 400).
    if (!validWebSocketKey(con->get_request_header("Sec-WebSocket-Key"))) {
      ++bad_key_refused_;
      return false;
    }
    for (const std::string& p : con->get_requested_subprotocols())
      if (p == kSubprotocol) {
        con->select_subprotocol(kSubprotocol);
        return true;
      }
    // Foxglove clients always ask for the subprotocol; a plain WebSocket gets the feed too.
    return con->get_requested_subprotocols().empty();
  });
  ws.set_open_handler([this](Hdl h) {
    auto con = impl_->ws.get_con_from_hdl(h);
    auto sink = std::make_unique<ConnSink>(con);
    const int id = impl_->hub->open(sink.get());
    if (id == 0) {
      websocketpp::lib::error_code e;
      impl_->ws.close(h, websocketpp::close::status::try_again_later, "too many clients", e);
      return;
    }
    impl_->conns[h] = {id, std::move(sink)};
  });
  auto closed = [this](Hdl h) {
    auto it = impl_->conns.find(h);
    if (it == impl_->conns.end()) return;
    impl_->hub->close(it->second.first);
    impl_->conns.erase(it);
  };
  ws.set_close_handler(closed);
  ws.set_fail_handler(closed);
  // A ping is answered (websocketpp queues a pong, with no bound of its own) only while the
  // client's queue is below the flow-control mark: a client that pings and never reads cannot
  // grow it (one did by 290 MB/s).
  ws.set_ping_handler([this](Hdl h, std::string) {
    websocketpp::lib::error_code e;
    auto con = impl_->ws.get_con_from_hdl(h, e);
    if (e || con->get_buffered_amount() >= impl_->pong_below_bytes) {
      ++pings_unanswered_;
      return false;
    }
    return true;
  });
  ws.set_message_handler([this](Hdl h, WsServer::message_ptr m) {
    auto it = impl_->conns.find(h);
    if (it == impl_->conns.end()) return;
    if (m->get_opcode() == websocketpp::frame::opcode::text) impl_->hub->onText(it->second.first, m->get_payload());
    else impl_->hub->onBinary(it->second.first, m->get_payload());
  });
  ws.set_http_handler([this](Hdl h) {
    ++http_requests_;
    auto con = impl_->ws.get_con_from_hdl(h);
    // At most kMaxHttpInFlight responses on their way at once (each holds its body until the
    // client has read it: 1,200 clients that never read held 1.7 GB); the rest: 503, counted.
    // And at most kMaxHttpPerAddress of them for one client address, so that one host that never
    // reads cannot take every slot (16 such connections kept the page from everyone else).
    auto& flight = impl_->http_in_flight;
    flight.erase(std::remove_if(flight.begin(), flight.end(), [](const auto& x) { return x.first.expired(); }), flight.end());
    boost::system::error_code aec;
    const auto ep = con->get_raw_socket().remote_endpoint(aec);
    const std::string addr = aec ? std::string("?") : ep.address().to_string();
    const auto same = std::count_if(flight.begin(), flight.end(), [&](const auto& x) { return x.second == addr; });
    if (static_cast<int>(flight.size()) >= kMaxHttpInFlight || same >= kMaxHttpPerAddress) {
      ++http_refused_;
      con->set_status(websocketpp::http::status_code::service_unavailable);
      con->replace_header("Retry-After", "1");
      con->set_body("busy\n");
      return;
    }
    flight.emplace_back(h, addr);
    std::string path = con->get_resource();
    const auto q = path.find('?');
    if (q != std::string::npos) path.resize(q);
    std::pair<std::string, std::shared_ptr<const std::string>> route;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      auto it = routes_.find(path);
      if (it != routes_.end()) route = it->second;
    }
    if (path == "/stats.json") {
      const Hub::Stats s = impl_->hub->stats();
      std::ostringstream j;
      j << "{\"clients\":" << s.clients << ",\"opened\":" << s.opened << ",\"closed\":" << s.closed
        << ",\"refused\":" << s.refused << ",\"published\":" << s.published << ",\"sent\":" << s.sent
        << ",\"dropped\":" << s.dropped << ",\"superseded\":" << s.superseded << ",\"rejected\":" << s.rejected << ",\"inbox_dropped\":" << inbox_dropped_.load()
        << ",\"client_published\":" << s.client_published << ",\"http_refused\":" << http_refused_.load()
        << ",\"pings_unanswered\":" << pings_unanswered_.load() << ",\"overflow_closed\":" << overflow_closed_.load()
        << ",\"old_protocol_refused\":" << old_protocol_refused_.load() << ",\"bad_key_refused\":" << bad_key_refused_.load()
        << ",\"per_client\":[";
      for (std::size_t i = 0; i < s.per_client.size(); ++i)
        j << (i ? "," : "") << "{\"id\":" << s.per_client[i].id << ",\"sent\":" << s.per_client[i].sent
          << ",\"dropped\":" << s.per_client[i].dropped << ",\"superseded\":" << s.per_client[i].superseded
          << ",\"waiting\":" << s.per_client[i].waiting << ",\"rejected\":" << s.per_client[i].rejected << "}";
      j << "]}";
      route = {"application/json", std::make_shared<const std::string>(j.str())};
    }
    if (!route.second) {
      ++http_not_found_;
      con->set_status(websocketpp::http::status_code::not_found);
      con->set_body("not found\n");
      return;
    }
    con->set_status(websocketpp::http::status_code::ok);
    con->replace_header("Content-Type", route.first);
    con->replace_header("Cache-Control", "no-store");
    con->set_body(*route.second);
  });

  boost::system::error_code bec;
  const auto addr = boost::asio::ip::make_address(o.bind, bec);
  if (bec) throw ServerError("--bind " + o.bind + ": not an IP address");
  if (o.port < 0 || o.port > 65535) throw ServerError("--port " + std::to_string(o.port) + ": must be in [0, 65535]");
  ws.listen(boost::asio::ip::tcp::endpoint(addr, static_cast<unsigned short>(o.port)), ec);
  if (ec) throw ServerError("cannot listen on " + o.bind + ":" + std::to_string(o.port) + ": " + ec.message());
  ws.start_accept(ec);
  if (ec) throw ServerError("cannot accept on " + o.bind + ":" + std::to_string(o.port) + ": " + ec.message());
  port_ = ws.get_local_endpoint(bec).port();
  if (bec) throw ServerError("cannot read the bound port: " + bec.message());
}

Server::~Server() { stop(); }

void Server::start() {
  // Every 10 ms: the waiting messages of clients whose queue drained go out (Hub::flush); every
  // 20th tick the Hub's counters are copied for other threads (five times a second).
  impl_->stats_timer = std::make_unique<boost::asio::steady_timer>(impl_->ws.get_io_service());
  auto copy = [this]() {
    const Hub::Stats s = impl_->hub->stats();
    std::lock_guard<std::mutex> lock(mutex_);
    stats_copy_ = s;
  };
  struct Ticker {
    Server* self;
    std::function<void()> copy;
    int tick = 0;
    void operator()(const boost::system::error_code& e) {
      if (e) return;
      self->impl_->hub->flush();
      // Whatever filled it (the Hub keeps its own sends below max_queued_bytes), a WebSocket
      // queue past twice that is a client that does not read: closed, counted.
      // (Handles first, then the closes: a close may run the close handler, which erases from conns.)
      std::vector<Hdl> over;
      for (auto& [h, c] : self->impl_->conns)
        if (c.second->buffered() > self->impl_->overflow_bytes) over.push_back(h);
      for (const Hdl& h : over) {
        websocketpp::lib::error_code ec;
        auto con = self->impl_->ws.get_con_from_hdl(h, ec);
        // (Once: a closing connection stays in conns, its queue still full, until the close
        // handshake times out.)
        if (ec || con->get_state() != websocketpp::session::state::open) continue;
        self->impl_->ws.close(h, websocketpp::close::status::policy_violation, "not reading", ec);
        if (!ec) ++self->overflow_closed_;
      }
      if (++tick % 20 == 0) copy();
      self->impl_->stats_timer->expires_after(std::chrono::milliseconds(10));
      self->impl_->stats_timer->async_wait(*this);
    }
  };
  impl_->stats_timer->expires_after(std::chrono::milliseconds(10));
  impl_->stats_timer->async_wait(Ticker{this, copy});
  thread_ = std::thread([this] {
    try {
      impl_->ws.run();
    } catch (const std::exception& e) {
      std::fprintf(stderr, "viewer: server thread: %s\n", e.what());
    }
  });
}

void Server::stop() {
  if (stopped_.exchange(true)) return;
  if (thread_.joinable()) {
    boost::asio::post(impl_->ws.get_io_service(), [this] {
      websocketpp::lib::error_code ec;
      impl_->ws.stop_listening(ec);
      if (impl_->stats_timer) impl_->stats_timer->cancel();
      for (auto& [h, c] : impl_->conns) impl_->ws.close(h, websocketpp::close::status::going_away, "viewer stopping", ec);
    });
    // Give the close frames a moment, then stop the loop whatever the clients do.
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    impl_->ws.stop();
    thread_.join();
  }
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stats_copy_ = impl_->hub->stats();
  }
}

void Server::publish(std::uint32_t channel, std::string key, std::string payload, std::uint64_t time_ns) {
  bool post = false;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (inbox_.size() >= inbox_capacity_) {
      inbox_.pop_front();
      ++inbox_dropped_;
    }
    inbox_.push_back(Pending{channel, std::move(key), std::move(payload), time_ns, false});
    post = !drain_posted_;
    drain_posted_ = true;
  }
  if (post) boost::asio::post(impl_->ws.get_io_service(), [this] { drain(); });
}

void Server::clearLatched(std::uint32_t channel) {
  bool post = false;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    inbox_.push_back(Pending{channel, {}, {}, 0, true});
    post = !drain_posted_;
    drain_posted_ = true;
  }
  if (post) boost::asio::post(impl_->ws.get_io_service(), [this] { drain(); });
}

void Server::drain() {
  std::deque<Pending> batch;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    batch.swap(inbox_);
    drain_posted_ = false;
  }
  for (Pending& p : batch) {
    if (p.clear) impl_->hub->clearLatched(p.channel);
    else impl_->hub->publish(p.channel, p.key, p.payload, p.time_ns);
  }
}

void Server::setRoute(const std::string& path, const std::string& content_type, std::shared_ptr<const std::string> body) {
  std::lock_guard<std::mutex> lock(mutex_);
  routes_[path] = {content_type, std::move(body)};
}

void Server::onClientPublish(std::function<void(const ClientPublish&)> handler) { impl_->hub->onClientPublish(std::move(handler)); }

Hub::Stats Server::stats() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return stats_copy_;
}

}  // namespace godhand::viewer
