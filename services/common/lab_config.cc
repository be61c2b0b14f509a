#include "common/lab_config.h"

#include <arpa/inet.h>
#include <google/protobuf/text_format.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <map>
#include <sstream>

#include "model/text_proto.h"

namespace godhand {

namespace {

namespace fs = std::filesystem;
using google::protobuf::FieldDescriptor;
using google::protobuf::Message;
using google::protobuf::TextFormat;

constexpr unsigned kMaxDomainId = 232;
constexpr double kDefaultDeadlineS = 10.0;
constexpr double kDefaultStaleAfterS = 0.25;


/// 1-based line of field `name` (element `index` of a repeated field, -1 for a singular one) of
/// `msg`, or `fallback` when the field is absent from the text (or unknown).
int lineOf(const Message& msg, const TextFormat::ParseInfoTree* tree, const std::string& name, int index, int fallback) {
  const FieldDescriptor* f = msg.GetDescriptor()->FindFieldByName(name);
  if (!tree || !f) return fallback;
  if (f->is_repeated()) {  // GetLocation insists on an index in range (the first element for -1)
    const int size = msg.GetReflection()->FieldSize(msg, f);
    if (size == 0) return fallback;
    index = index < 0 ? 0 : index;
    if (index >= size) return fallback;
  } else {
    index = -1;
  }
  const auto loc = tree->GetLocation(f, index);
  return loc.line >= 0 ? loc.line + 1 : fallback;
}

std::string inQuotes(const std::string& s) { return "\"" + s + "\""; }

std::string num(double x) {
  std::ostringstream os;
  os.precision(6);
  os << x;
  return os.str();
}

std::string lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

bool validClusterName(const std::string& s) {
  if (s.empty() || s.size() > 31) return false;
  for (char c : s)
    if (!((c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_' || c == '-')) return false;
  return true;
}

bool validHostName(const std::string& s) {
  if (s.empty() || s.size() > 63) return false;
  for (char c : s)
    if (!((c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '.' || c == '-')) return false;
  return true;
}

bool validIpv4(const std::string& s) {
  in_addr a{};
  return inet_pton(AF_INET, s.c_str(), &a) == 1;
}

/// Builds "SOURCE:LINE: PATH: reason" errors for one message of the file.
class Where {
 public:
  Where(const std::string& source, const Message& msg, const TextFormat::ParseInfoTree* tree, int line, std::string path)
      : source_(source), msg_(msg), tree_(tree), line_(line), path_(std::move(path)) {}

  /// The error for field `field` of this message ("" = the message itself).
  [[noreturn]] void fail(const std::string& field, const std::string& reason) const {
    const int line = field.empty() ? line_ : lineOf(msg_, tree_, field, -1, line_);
    std::string path = path_;
    if (!field.empty()) path += (path.empty() ? "" : ".") + field;
    throw LabError(source_ + ":" + std::to_string(line) + ": " + path + ": " + reason);
  }

 private:
  const std::string& source_;
  const Message& msg_;
  const TextFormat::ParseInfoTree* tree_;
  int line_;
  std::string path_;
};

/// Absolute, normalised path of `value` (relative to `base_dir`), which must name a readable
/// regular file; `what` names it in errors ("model", "scene file", ...).
std::string existingFile(const std::string& value, const fs::path& base_dir, const Where& where, const std::string& field,
                         const std::string& what) {
  const fs::path p(value);
  const std::string full = (p.is_absolute() ? p : base_dir / p).lexically_normal().string();
  const std::string shown = inQuotes(value) + (value == full ? "" : " (" + full + ")");
  std::error_code ec;
  const fs::file_status st = fs::status(full, ec);
  if (!fs::exists(st)) where.fail(field, what + " " + shown + " does not exist");
  if (fs::is_directory(st)) where.fail(field, what + " " + shown + " is a directory, not a file");
  if (::access(full.c_str(), R_OK) != 0) where.fail(field, what + " " + shown + " is not readable: " + std::strerror(errno));
  return full;
}

}  // namespace

std::string labServiceName(pb::Service::Kind kind, const std::string& cluster) {
  switch (kind) {
    case pb::Service::INGEST: return "ingest";
    case pb::Service::SCENE: return "scene";
    case pb::Service::RESOLVER: return "resolver";
    case pb::Service::SOLVER: return "solver/" + cluster;
    default: return "";
  }
}

bool isLocalHost(const std::string& host) {
  const std::string h = lower(host);
  if (h.empty() || h == "localhost" || h == "127.0.0.1" || h == "::1") return true;
  char buf[256] = {};
  if (::gethostname(buf, sizeof buf - 1) != 0) return false;
  return h == lower(buf);
}

const LabCluster* LabConfig::cluster(const std::string& cluster_name) const {
  for (const LabCluster& c : clusters)
    if (c.name == cluster_name) return &c;
  return nullptr;
}

const LabService* LabConfig::service(const std::string& service_name) const {
  for (const LabService& s : services)
    if (s.name == service_name) return &s;
  return nullptr;
}

const LabHost* LabConfig::host(const std::string& host_name) const {
  for (const LabHost& h : hosts)
    if (h.name == host_name) return &h;
  return nullptr;
}

void selectHost(LabConfig& lab, const std::string& name) {
  std::string known;
  if (!lab.hosts.empty()) {
    if (const LabHost* h = lab.host(name)) {
      if (!h->profiles.empty()) lab.profiles = h->profiles;
      return;
    }
    for (const LabHost& h : lab.hosts) known += (known.empty() ? "" : ", ") + h.name;
  } else {
    std::map<std::string, int> seen;
    for (const LabService& s : lab.services) {
      if (s.host == name && !name.empty()) return;
      if (!s.host.empty() && seen.emplace(s.host, 0).second) known += (known.empty() ? "" : ", ") + s.host;
    }
  }
  throw LabError(lab.file + ": --host " + inQuotes(name) + ": no such host in the lab (hosts: " +
                 (known.empty() ? "none named" : known) + ")");
}

bool runsHere(const LabService& s, const std::string& host) { return host.empty() ? s.local : s.host == host; }

LabConfig parseLab(const std::string& text, const std::string& source, const std::string& base_dir) {
  pb::Lab msg;
  TextFormat::ParseInfoTree tree;
  std::string syntax;
  if (!parseTextProto(text, &msg, &tree, &syntax, "0: unparsable lab file")) throw LabError(source + ":" + syntax);

  std::error_code ec;
  fs::path base = fs::absolute(base_dir.empty() ? fs::path(".") : fs::path(base_dir), ec);
  if (ec) base = fs::path(base_dir);
  base = base.lexically_normal();

  const Where top(source, msg, &tree, 1, "");
  LabConfig lab;
  lab.file = source;
  lab.name = msg.name().empty() ? fs::path(source).stem().string() : msg.name();

  if (msg.domain_id() > kMaxDomainId)
    top.fail("domain_id", "must lie in 0.." + std::to_string(kMaxDomainId) + " (Fast DDS maps it to UDP ports), got " +
                              std::to_string(msg.domain_id()));
  lab.domain_id = static_cast<int>(msg.domain_id());

  if (!msg.profiles().empty()) lab.profiles = existingFile(msg.profiles(), base, top, "profiles", "Fast DDS profiles file");
  if (msg.scene().empty()) top.fail("scene", "a lab needs a scene file (scene: \"...pbtxt\")");
  lab.scene = existingFile(msg.scene(), base, top, "scene", "scene file");
  if (!msg.recording().empty()) lab.recording = existingFile(msg.recording(), base, top, "recording", "recording");

  if (msg.deadline_s() != 0.0) {
    if (!std::isfinite(msg.deadline_s()) || msg.deadline_s() < 0.0 || msg.deadline_s() > 3600.0)
      top.fail("deadline_s", "must be a number of seconds in (0, 3600] (0 or absent = 10), got " + num(msg.deadline_s()));
    lab.deadline_s = msg.deadline_s();
  } else {
    lab.deadline_s = kDefaultDeadlineS;
  }
  if (msg.stale_after_s() != 0.0) {
    if (!std::isfinite(msg.stale_after_s()) || msg.stale_after_s() < 0.0 || msg.stale_after_s() > 3600.0)
      top.fail("stale_after_s",
               "must be a number of seconds in (0, 3600] (0 or absent = 0.25), got " + num(msg.stale_after_s()));
    lab.stale_after_s = msg.stale_after_s();
  } else {
    lab.stale_after_s = kDefaultStaleAfterS;
  }

  // Clusters.
  if (msg.clusters_size() == 0) top.fail("clusters", "a lab needs at least one cluster (clusters { name model side })");
  if (msg.clusters_size() > kMaxLabClusters)
    top.fail("clusters", std::to_string(msg.clusters_size()) + " clusters; a lab has at most " + std::to_string(kMaxLabClusters) +
                             " (the resolver merges at most that many)");
  const FieldDescriptor* f_clusters = msg.GetDescriptor()->FindFieldByName("clusters");
  std::map<std::string, int> cluster_index;
  std::vector<int> cluster_line;
  for (int i = 0; i < msg.clusters_size(); ++i) {
    const pb::Cluster& pc = msg.clusters(i);
    const int line = lineOf(msg, &tree, "clusters", i, 1);
    cluster_line.push_back(line);
    const Where where(source, pc, tree.GetTreeForNested(f_clusters, i), line, "clusters[" + std::to_string(i) + "]");
    LabCluster c;
    c.index = i;
    c.name = pc.name();
    if (!validClusterName(c.name))
      where.fail("name", "a cluster name must be 1 to 31 characters of a-z, 0-9, '_' and '-', got " + inQuotes(c.name));
    const auto [it, fresh] = cluster_index.emplace(c.name, i);
    if (!fresh)
      where.fail("name", "duplicate cluster name " + inQuotes(c.name) + " (also clusters[" + std::to_string(it->second) + "])");
    c.side = pc.side();
    if (pc.has_tracker_body()) {
      if (pc.tracker_body() < 0 || pc.tracker_body() > 1000)
        where.fail("tracker_body", "a tracked body id is 0 to 1000, got " + std::to_string(pc.tracker_body()));
      if (!c.side.empty())
        where.fail("side", "a tool cluster (tracker_body " + std::to_string(pc.tracker_body()) +
                               ") is driven by that body, not by a hand: remove side " + inQuotes(c.side));
      c.tracker_body = pc.tracker_body();
    } else if (c.side != "right" && c.side != "left") {
      where.fail("side", "must be \"right\" or \"left\" (or give tracker_body N for a tool), got " + inQuotes(c.side));
    }
    if (pc.model().empty()) where.fail("model", "cluster " + inQuotes(c.name) + " needs a hand model file");
    c.model = existingFile(pc.model(), base, where, "model", "hand model");
    lab.clusters.push_back(std::move(c));
  }

  // Hosts.
  const FieldDescriptor* f_hosts = msg.GetDescriptor()->FindFieldByName("hosts");
  std::map<std::string, int> host_index, address_index;
  for (int i = 0; i < msg.hosts_size(); ++i) {
    const pb::Host& ph = msg.hosts(i);
    const int line = lineOf(msg, &tree, "hosts", i, 1);
    const Where where(source, ph, tree.GetTreeForNested(f_hosts, i), line, "hosts[" + std::to_string(i) + "]");
    LabHost h;
    h.name = ph.name();
    if (!validHostName(h.name))
      where.fail("name", "a host name must be 1 to 63 characters of A-Z, a-z, 0-9, '.' and '-', got " + inQuotes(h.name));
    const auto [it, fresh] = host_index.emplace(h.name, i);
    if (!fresh) where.fail("name", "duplicate host name " + inQuotes(h.name) + " (also hosts[" + std::to_string(it->second) + "])");
    h.address = ph.address();
    if (!validIpv4(h.address))
      where.fail("address", "host " + inQuotes(h.name) + " needs its IPv4 address on the lab network (a.b.c.d), got " +
                                inQuotes(h.address));
    const auto [ia, afresh] = address_index.emplace(h.address, i);
    if (!afresh)
      where.fail("address", "address " + h.address + " is also that of hosts[" + std::to_string(ia->second) + "]");
    if (!ph.profiles().empty()) h.profiles = existingFile(ph.profiles(), base, where, "profiles", "Fast DDS profiles file");
    lab.hosts.push_back(std::move(h));
  }
  std::string host_names;
  for (const LabHost& h : lab.hosts) host_names += (host_names.empty() ? "" : ", ") + h.name;
  if (!msg.discovery_server().empty()) {
    if (!host_index.count(msg.discovery_server()))
      top.fail("discovery_server", "no host named " + inQuotes(msg.discovery_server()) + " (hosts: " +
                                       (host_names.empty() ? "none" : host_names) + ")");
    lab.discovery_server = msg.discovery_server();
  }
  if (msg.discovery_port() != 0) {
    if (msg.discovery_port() > 65535) top.fail("discovery_port", "must lie in 1..65535, got " + std::to_string(msg.discovery_port()));
    lab.discovery_port = static_cast<int>(msg.discovery_port());
  }

  if (!msg.security().empty()) {
    if (!lab.discovery_server.empty())
      top.fail("security", "DDS-Security and a discovery server do not work together with Fast DDS 2.9.1 (the server's "
                           "GUID prefix is derived from its certificate): leave discovery_server empty");
    const fs::path sp(msg.security());
    lab.security = (sp.is_absolute() ? sp : base / sp).lexically_normal().string();
  }

  if (msg.has_tracker()) {
    const pb::Tracker& t = msg.tracker();
    lab.tracker = {t.pose(), t.units(), t.up(), t.hand_map(), t.palm_offset(), t.tracking_volume_m(), t.max_speed_mps()};
    if (!std::isfinite(t.tracking_volume_m()) || t.tracking_volume_m() < 0.0)
      top.fail("tracker.tracking_volume_m", "must be a finite number of metres >= 0 (0 = 50 m), got " + num(t.tracking_volume_m()));
    if (!std::isfinite(t.max_speed_mps()) || t.max_speed_mps() < 0.0)
      top.fail("tracker.max_speed_mps", "must be a finite speed >= 0 (0 = 30 m/s), got " + num(t.max_speed_mps()));
  }

  // Services.
  const FieldDescriptor* f_services = msg.GetDescriptor()->FindFieldByName("services");
  std::map<std::string, int> service_index;  // name -> index in the file
  for (int i = 0; i < msg.services_size(); ++i) {
    const pb::Service& ps = msg.services(i);
    const int line = lineOf(msg, &tree, "services", i, 1);
    const Where where(source, ps, tree.GetTreeForNested(f_services, i), line, "services[" + std::to_string(i) + "]");
    LabService s;
    s.kind = ps.kind();
    switch (s.kind) {
      case pb::Service::INGEST:
      case pb::Service::SCENE:
      case pb::Service::RESOLVER:
        if (!ps.cluster().empty())
          where.fail("cluster", "cluster applies to SOLVER services only (this one is " +
                                    pb::Service::Kind_Name(s.kind) + ")");
        break;
      case pb::Service::SOLVER:
        if (ps.cluster().empty()) where.fail("cluster", "a SOLVER service needs the name of its cluster (cluster: \"...\")");
        if (!cluster_index.count(ps.cluster())) {
          std::string names;
          for (const LabCluster& c : lab.clusters) names += (names.empty() ? "" : ", ") + c.name;
          where.fail("cluster", "no cluster named " + inQuotes(ps.cluster()) + " (clusters: " + names + ")");
        }
        s.cluster = ps.cluster();
        break;
      case pb::Service::KIND_UNSPECIFIED:
        where.fail("kind", "every service needs a kind: INGEST, SOLVER, SCENE or RESOLVER");
      default:
        where.fail("kind", "unknown service kind " + std::to_string(static_cast<int>(s.kind)));
    }
    s.name = labServiceName(s.kind, s.cluster);
    const auto [it, fresh] = service_index.emplace(s.name, i);
    if (!fresh) {
      const std::string first = "services[" + std::to_string(it->second) + "]";
      if (s.kind == pb::Service::SOLVER)
        where.fail("cluster", "second SOLVER for cluster " + inQuotes(s.cluster) + " (the first is " + first + ")");
      where.fail("kind", "second " + pb::Service::Kind_Name(s.kind) + " service (the first is " + first +
                             "); a lab runs exactly one");
    }
    s.host = ps.host();
    if (!lab.hosts.empty() && !host_index.count(s.host))
      where.fail("host", (s.host.empty() ? std::string("a lab with hosts needs the host of every service")
                                         : "no host named " + inQuotes(s.host)) +
                             " (hosts: " + host_names + ")");
    s.local = isLocalHost(s.host);
    s.args.assign(ps.args().begin(), ps.args().end());
    // The options godhand-launch gives every service from the lab itself: a service's args may
    // not give them again (a second --domain would take the service into another domain).
    for (const std::string& a : s.args) {
      const std::string opt = a.substr(0, a.find('='));
      for (const char* mine : {"--lab", "--domain", "--profiles", "--frame-rate", "--scene", "--lockstep", "--cluster",
                               "--source", "--partition"})
        if (opt == mine)
          where.fail("args", "args may not set " + opt + ": godhand-launch sets it from the lab (and its own options)");
    }
    lab.services.push_back(std::move(s));
  }
  const int services_line = msg.services_size() > 0 ? lineOf(msg, &tree, "services", 0, 1) : 1;
  for (const pb::Service::Kind kind : {pb::Service::INGEST, pb::Service::SCENE, pb::Service::RESOLVER}) {
    if (!service_index.count(labServiceName(kind, "")))
      throw LabError(source + ":" + std::to_string(services_line) + ": services: no " + pb::Service::Kind_Name(kind) +
                     " service (a lab runs exactly one INGEST, one SCENE, one RESOLVER and one SOLVER per cluster)");
  }
  for (const LabCluster& c : lab.clusters) {
    if (!service_index.count(labServiceName(pb::Service::SOLVER, c.name)))
      throw LabError(source + ":" + std::to_string(cluster_line[static_cast<size_t>(c.index)]) + ": clusters[" +
                     std::to_string(c.index) + "]: no SOLVER service for cluster " + inQuotes(c.name) +
                     " (add services { kind: SOLVER cluster: " + inQuotes(c.name) + " })");
  }
  return lab;
}

LabConfig loadLab(const std::string& path) {
  std::error_code ec;
  if (fs::is_directory(path, ec)) throw LabError(path + ":0: cannot read lab file: it is a directory");
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (!f) throw LabError(path + ":0: cannot read lab file: " + std::strerror(errno));
  std::string text;
  char buf[65536];
  size_t n;
  while ((n = std::fread(buf, 1, sizeof buf, f)) > 0) text.append(buf, n);
  const bool failed = std::ferror(f) != 0;
  const int err = errno;
  std::fclose(f);
  if (failed) throw LabError(path + ":0: cannot read lab file: " + std::strerror(err));

  fs::path abs = fs::absolute(path, ec);
  if (ec) abs = fs::path(path);
  abs = abs.lexically_normal();
  LabConfig lab = parseLab(text, path, abs.parent_path().string());
  lab.file = abs.string();
  return lab;
}

}  // namespace godhand
