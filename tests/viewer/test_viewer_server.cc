// The viewer's HTTP side against clients that never read (services/viewer/server.cc): at most
// Server::kMaxHttpInFlight responses on their way at once and at most kMaxHttpPerAddress of them
// for one client address, so that one host cannot keep the page from everyone else. A real
// Server on loopback and real sockets with a small receive buffer that are never read.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "viewer/server.h"

namespace godhand::viewer {
namespace {

/// A TCP connection from `from` (a 127.x address) to 127.0.0.1:port with a 4 KB receive buffer.
int connectFrom(const char* from, int port) {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  if (fd < 0) return -1;
  const int small = 4096;
  ::setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &small, sizeof small);
  sockaddr_in local{};
  local.sin_family = AF_INET;
  ::inet_pton(AF_INET, from, &local.sin_addr);
  if (::bind(fd, reinterpret_cast<sockaddr*>(&local), sizeof local) != 0) {
    ::close(fd);
    return -1;
  }
  sockaddr_in to{};
  to.sin_family = AF_INET;
  to.sin_port = htons(static_cast<std::uint16_t>(port));
  ::inet_pton(AF_INET, "127.0.0.1", &to.sin_addr);
  if (::connect(fd, reinterpret_cast<sockaddr*>(&to), sizeof to) != 0) {
    ::close(fd);
    return -1;
  }
  // A read never waits longer than this: long enough for a server under a sanitizer on a loaded
  // machine (it failed there at 5 s: the server was still writing the hogs' 32 MB responses).
  timeval tv{30, 0};
  ::setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
  return fd;
}

bool request(int fd, const std::string& path) {
  const std::string r = "GET " + path + " HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n";
  return ::send(fd, r.data(), r.size(), MSG_NOSIGNAL) == static_cast<ssize_t>(r.size());
}

/// The status code of one request from `from` ("" when there is no answer within 30 s).
std::string statusFrom(const char* from, int port, const std::string& path) {
  const int fd = connectFrom(from, port);
  if (fd < 0) return "no connection";
  std::string head;
  if (request(fd, path)) {
    char buf[512];
    while (head.find("\r\n") == std::string::npos) {
      const ssize_t n = ::recv(fd, buf, sizeof buf, 0);
      if (n <= 0) break;
      head.append(buf, static_cast<size_t>(n));
    }
  }
  ::close(fd);
  const size_t sp = head.find(' ');
  return sp == std::string::npos ? "" : head.substr(sp + 1, 3);
}

/// Waits (at most 30 s) until the server has taken `n` HTTP requests; false if it has not.
bool requestsTaken(const Server& server, std::uint64_t n) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  while (server.httpRequests() < n) {
    if (std::chrono::steady_clock::now() > deadline) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return true;
}

// The page's two files in a folder of their own under the test's temporary folder, and server
// options serving them.
ServerOptions pageOptions(const std::string& name) {
  const std::string root = ::testing::TempDir() + "/" + name;
  EXPECT_EQ(std::system(("mkdir -p " + root).c_str()), 0);
  std::ofstream(root + "/index.html") << "<html></html>\n";
  std::ofstream(root + "/viewer.js") << "// page\n";
  ServerOptions o;
  o.web_root = root;
  return o;
}

// `n` clients from address `from` that ask for /big and never read it.
void openHogs(const char* from, int port, int n, std::vector<int>* fds) {
  for (int i = 0; i < n; ++i) {
    const int fd = connectFrom(from, port);
    ASSERT_GE(fd, 0);
    ASSERT_TRUE(request(fd, "/big"));
    fds->push_back(fd);
  }
}

// The status of /index.html from 127.0.0.1 once it is 200, polled for at most 30 s (the last
// status then).
std::string statusOnceServed(int port) {
  std::string status;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  while (status != "200" && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    status = statusFrom("127.0.0.1", port, "/index.html");
  }
  return status;
}

// 32 MB: more than any socket buffers between the server and a client that does not read.
std::shared_ptr<const std::string> bigBody() { return std::make_shared<const std::string>(std::string(32u << 20, 'x')); }

// A client that never reads its response is dropped once the handshake timeout has passed: its
// HTTP slot is free again while its socket is still open on the client's side.
TEST(ViewerServer, AClientThatNeverReadsIsDroppedAfterTheHandshakeTimeout) {
  ServerOptions o = pageOptions("viewer_root_timeout");
  o.handshake_timeout_ms = 1000;
  Server server(o);
  server.setRoute("/big", "application/octet-stream", bigBody());
  server.start();
  const int port = server.port();
  std::vector<int> hogs;
  const auto first = std::chrono::steady_clock::now();  // (the timeout runs from each accept)
  openHogs("127.0.0.1", port, Server::kMaxHttpPerAddress, &hogs);
  ASSERT_TRUE(requestsTaken(server, static_cast<std::uint64_t>(Server::kMaxHttpPerAddress)));
  // Refused while the hogs hold the address's share (checked where the timeout cannot have passed).
  const std::string during = statusFrom("127.0.0.1", port, "/index.html");
  if (std::chrono::steady_clock::now() - first < std::chrono::milliseconds(800)) {
    EXPECT_EQ(during, "503");
  }
  EXPECT_EQ(statusOnceServed(port), "200") << "the hogs' slots freed by the server (their sockets still open here)";
  for (int fd : hogs) ::close(fd);
  server.stop();
  ServerOptions bad = o;
  bad.handshake_timeout_ms = 0;
  EXPECT_THROW(Server{bad}, ServerError);
}

TEST(ViewerServer, ClientsThatNeverReadHoldOnlyTheirAddresssShareOfTheHttpSlots) {
  ServerOptions o = pageOptions("viewer_root");
  // The hogs hold their slots for the whole test: with the default 5 s the server dropped the
  // first ones before the last check on a loaded machine (CI, 2026-12-07: 11.5 s for the test,
  // "200" where "503" was due). The drop itself: AClientThatNeverReadsIsDroppedAfterTheHandshakeTimeout.
  o.handshake_timeout_ms = 300000;
  Server server(o);
  server.setRoute("/big", "application/octet-stream", bigBody());
  server.start();
  const int port = server.port();
  ASSERT_EQ(statusFrom("127.0.0.1", port, "/index.html"), "200");

  std::vector<int> hogs;
  openHogs("127.0.0.1", port, Server::kMaxHttpPerAddress, &hogs);
  // The server has taken every hog's request (each then holds its slot until its client reads).
  ASSERT_TRUE(requestsTaken(server, 1 + static_cast<std::uint64_t>(Server::kMaxHttpPerAddress)));
  EXPECT_EQ(statusFrom("127.0.0.1", port, "/index.html"), "503") << "one address holds at most its share";
  EXPECT_EQ(statusFrom("127.0.0.2", port, "/index.html"), "200") << "another address is served meanwhile";
  // Two more addresses of hogs fill the server's 16 slots: then everyone waits.
  std::vector<int> more;
  for (const char* from : {"127.0.0.3", "127.0.0.4"}) openHogs(from, port, Server::kMaxHttpPerAddress, &more);
  ASSERT_TRUE(requestsTaken(server, 3 + 3 * static_cast<std::uint64_t>(Server::kMaxHttpPerAddress)));
  EXPECT_EQ(statusFrom("127.0.0.5", port, "/index.html"), "503") << Server::kMaxHttpInFlight << " slots in all";
  EXPECT_GE(server.httpRefused(), 3u);
  for (int fd : hogs) ::close(fd);
  for (int fd : more) ::close(fd);
  // Gone clients free their slots.
  EXPECT_EQ(statusOnceServed(port), "200");
  server.stop();
}

}  // namespace
}  // namespace godhand::viewer
