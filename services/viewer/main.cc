// godhand-viewer: the browser viewer. Live: a DDS participant (profiles from XML) that subscribes
// to HandState, HandTarget, SceneDescription, SceneState, ContactForces and ServiceStatus and
// forwards them as JSON over the Foxglove WebSocket protocol (feed.h) to every connected page,
// with the scene's meshes served over HTTP on the same port. Offline (--poses): serves a
// godhand-bench --poses CSV and its scene, no DDS. Wiring only: the rules live in feed.cc,
// encode.cc, offline.cc and server.cc.
#include <algorithm>
#include <cstdio>
#include <future>
#include <memory>
#include <mutex>

#include "common/cli.h"
#include "common/files.h"
#include "common/lab_config.h"
#include "common/signals.h"
#include "dds/dds.h"
#include "dds/topics.h"
#include "leap/leap_recording.h"
#include "pipeline/collision_world.h"
#include "runtime/convert.h"
#include "runtime/service.h"
#include "scene/scene_file.h"
#include "viewer/encode.h"
#include "viewer/offline.h"
#include "viewer/server.h"
#include "viewer/synthetic.h"

using namespace godhand;
using namespace godhand::viewer;
using nlohmann::json;

namespace {
constexpr const char* kSynopsis =
    "The browser viewer. Live: subscribes to the hands, targets, scene, forces and service heartbeats of a\n"
    "DDS domain and serves a page that draws them (God hands solid, targets as ghosts, contacts, live\n"
    "figures) plus a Foxglove WebSocket feed (subprotocol foxglove.websocket.v1, JSON channels) on one port.\n"
    "Offline (--poses FILE): plays a godhand-bench --poses CSV over its scene (--scene, or --mesh with the\n"
    "--recording it was centred on, as godhand-bench takes them). Prints 'viewer: http://ADDR:PORT/'.";

std::shared_ptr<const std::string> shared(std::string s) { return std::make_shared<const std::string>(std::move(s)); }

// The meshes of a scene as HTTP routes /mesh/GEN/INDEX.bin (about max_triangles each) and
// /mesh/GEN/INDEX.light.bin (a quarter of that: what a page drawing in software fetches).
void serveMeshes(Server& server, const Scene& scene, const std::string& gen, int max_triangles) {
  geo::TriangleMesh m;
  for (int i = 0; i < static_cast<int>(scene.objects.size()); ++i) {
    const std::string route = "/mesh/" + gen + "/" + std::to_string(i);
    if (displayMesh(scene, i, max_triangles, &m)) server.setRoute(route + ".bin", "application/octet-stream", shared(meshBinary(m)));
    if (displayMesh(scene, i, std::max(4, max_triangles / 4), &m))
      server.setRoute(route + ".light.bin", "application/octet-stream", shared(meshBinary(m)));
  }
}

struct LoadedScene {
  std::string file;
  std::unique_ptr<Scene> scene;
  std::string error;
};
}  // namespace

int main(int argc, char** argv) {
  Cli cli("godhand-viewer", kSynopsis);
  std::string lab_file = std::string(GODHAND_DEPLOY_DIR) + "/lab/local.pbtxt";
  int domain = -1;
  std::string profiles, bind = "127.0.0.1", web_root = GODHAND_VIEWER_WEB_ROOT, poses, scene_file, recording;
  std::vector<std::string> meshes;
  int port = 0;
  double max_queue_mb = 4.0;
  int display_triangles = 12000;
  bool quiet = false;
  std::string synthetic;
  cli.option("--lab", &lab_file, "FILE", "lab configuration (domain, profiles) of the live mode");
  cli.option("--domain", &domain, "N", "DDS domain id 0..232; -1 = the lab's");
  cli.option("--profiles", &profiles, "FILE", "Fast DDS XML profiles (default: the lab's, else deploy/dds/godhand-local.xml)");
  cli.option("--bind", &bind, "ADDR", "address to serve on (keep 127.0.0.1 unless you mean to expose it)");
  cli.option("--port", &port, "PORT", "TCP port; 0 = a free one (printed)");
  cli.option("--web-root", &web_root, "DIR", "the built page (index.html, viewer.js)");
  cli.option("--max-queue-mb", &max_queue_mb, "MB",
             "per browser: a message larger than this is dropped (counted); a browser with more than the smaller of this "
             "and 0.25 MB queued gets only the newest message of each channel and hand, the older ones counted as dropped");
  cli.option("--display-triangles", &display_triangles, "N", "the page draws each object decimated to about N triangles (collisions use the full mesh); a page drawing in software a quarter of that");
  cli.option("--poses", &poses, "FILE", "offline: a godhand-bench --poses CSV to play (no DDS)");
  cli.option("--scene", &scene_file, "FILE", "offline: the scene file the bench ran on (default: the lab's)");
  cli.multi("--mesh", &meshes, "FILE[:SIZE_M][@X,Y,Z]", "offline: the bench's ad-hoc mesh scene (needs --recording)");
  cli.option("--recording", &recording, "FILE", "offline with --mesh: the recording the meshes were centred on");
  cli.option("--synthetic", &synthetic, "CLUSTER",
             "live: the page drives this cluster's hand (keys / Shift-drag): the viewer publishes its HandTarget at the lab's\n"
             "frame rate; run the services with a silent tracker source (see README, Viewer)");
  cli.flag("--quiet", &quiet, "no per-second line on stderr");
  cli.epilog("Exit status: 0 after SIGINT/SIGTERM, 2 on a bad configuration (one line on stderr).");
  cli.parse(argc, argv);

  installStopHandlers();
  if (domain < -1 || domain > 232) cli.fail("--domain must be in 0..232");
  if (port < 0 || port > 65535) cli.fail("--port must be in 0..65535");
  if (display_triangles < 4 || display_triangles > 10000000) cli.fail("--display-triangles must be in [4, 10000000]");
  if (!(max_queue_mb >= 0.01 && max_queue_mb <= 1024)) cli.fail("--max-queue-mb must be in [0.01, 1024]");
  const bool offline = !poses.empty();
  if (!offline && (!meshes.empty() || !recording.empty())) cli.fail("--mesh and --recording are for the offline mode (--poses FILE)");
  if (!scene_file.empty() && !meshes.empty()) cli.fail("--scene and --mesh exclude each other");
  if (!meshes.empty() && recording.empty()) cli.fail("--mesh needs the --recording it was centred on");
  if (offline && !synthetic.empty()) cli.fail("--synthetic is for the live mode");

  LabConfig lab;
  if (!offline || (scene_file.empty() && meshes.empty())) {
    try {
      lab = loadLab(lab_file);
    } catch (const std::exception& e) {
      cli.fail(e.what());
    }
  }

  // The synthetic hand: its cluster, model and start pose (above the bunny of the lab's scene).
  int synthetic_hand = -1;
  HandModel synthetic_model;
  Pose synthetic_start;
  double synthetic_rate = 60.0;
  if (!synthetic.empty()) {
    for (const LabCluster& c : lab.clusters)
      if (c.name == synthetic) synthetic_hand = c.index;
    if (synthetic_hand < 0) cli.fail("--synthetic " + synthetic + ": no such cluster in " + lab.file);
    try {
      synthetic_model = loadHandModel(lab.clusters[static_cast<std::size_t>(synthetic_hand)].model);
      synthetic_start = syntheticStart(loadScene(lab.scene));
      if (!lab.recording.empty()) synthetic_rate = svc::recordingFrameRate(lab.recording);
      if (!(synthetic_rate >= 1.0 && synthetic_rate <= 1000.0)) synthetic_rate = 60.0;  // no usable rate: 60 Hz
    } catch (const std::exception& e) {
      cli.fail(e.what());
    }
  }

  // Offline inputs, checked before anything is served.
  PoseFile pose_file;
  Scene offline_scene;
  std::string offline_scene_name;
  if (offline) {
    try {
      pose_file = loadPosesCsv(poses);
      if (!meshes.empty()) {
        std::vector<MeshSpec> specs;
        for (const std::string& m : meshes) specs.push_back(parseMeshSpec(m));
        const leap::Recording rec = leap::Recording::load(recording);
        offline_scene = meshScene(specs, rec.meanPalmPosition(), meshFileLoader());
        offline_scene_name = "--mesh";
      } else {
        offline_scene_name = scene_file.empty() ? lab.scene : scene_file;
        offline_scene = loadScene(offline_scene_name);
      }
    } catch (const std::exception& e) {
      cli.fail(e.what());
    }
  }

  ServerOptions so;
  so.bind = bind;
  so.port = port;
  so.web_root = web_root;
  so.limits.max_queued_bytes = static_cast<std::size_t>(max_queue_mb * 1024 * 1024);
  so.limits.send_below_bytes = std::min(so.limits.send_below_bytes, so.limits.max_queued_bytes);
  std::unique_ptr<Server> server;
  try {
    server = std::make_unique<Server>(so);
  } catch (const std::exception& e) {
    cli.fail(e.what());
  }

  if (offline) {
    serveMeshes(*server, offline_scene, "1", display_triangles);
    json data = poseFileJson(pose_file);
    data["scene"] = sceneJson(offline_scene, offline_scene_name, "1");
    data["poses_file"] = poses;
    server->setRoute("/offline.json", "application/json", shared(data.dump()));
    server->setRoute("/mode.json", "application/json", shared(json{{"mode", "offline"}}.dump()));
    server->start();
    std::printf("viewer: http://%s:%d/\n", bind.c_str(), server->port());
    std::fflush(stdout);
    std::fprintf(stderr, "viewer: offline, %s: %zu frames, %zu hands, %zu rows%s; scene '%s' (%zu objects)\n", poses.c_str(),
                 pose_file.frames.size(), pose_file.hands.size(), pose_file.rows, pose_file.has_targets ? ", with targets" : "",
                 offline_scene.name.c_str(), offline_scene.objects.size());
    while (!waitForStop(std::chrono::milliseconds(500))) {
    }
    server->stop();
    const Hub::Stats s = server->stats();
    std::fprintf(stderr, "viewer: stopped; http requests %llu, browsers %llu\n",
                 static_cast<unsigned long long>(server->httpRequests()), static_cast<unsigned long long>(s.opened));
    return 0;
  }

  // Live.
  dds::Options dopt;
  dopt.domain = domain >= 0 ? domain : lab.domain_id;
  dopt.profiles = profiles.empty() ? lab.profiles : profiles;
  dopt.name = "viewer";
  std::unique_ptr<dds::Participant> participant;
  try {
    participant = std::make_unique<dds::Participant>(dopt);
  } catch (const std::exception& e) {
    cli.fail(e.what());
  }
  using dds::Reader;
  namespace topic = dds::topic;
  namespace profile = dds::profile;
  std::unique_ptr<Reader<msg::HandState>> states_p;
  std::unique_ptr<Reader<msg::HandTarget>> targets_p;
  std::unique_ptr<Reader<msg::SceneDescription>> descriptions_p;
  std::unique_ptr<Reader<msg::SceneState>> scenes_p;
  std::unique_ptr<Reader<msg::ContactForces>> forces_p;
  std::unique_ptr<Reader<msg::ServiceStatus>> status_p;
  std::unique_ptr<dds::Writer<msg::HandTarget>> synthetic_p;
  try {
    if (synthetic_hand >= 0)
      synthetic_p = std::make_unique<dds::Writer<msg::HandTarget>>(*participant, topic::kHandTarget, profile::kStreamLive);
    states_p = std::make_unique<Reader<msg::HandState>>(*participant, topic::kHandState, profile::kState);
    targets_p = std::make_unique<Reader<msg::HandTarget>>(*participant, topic::kHandTarget, profile::kStreamLive);
    descriptions_p = std::make_unique<Reader<msg::SceneDescription>>(*participant, topic::kSceneDescription, profile::kState);
    scenes_p = std::make_unique<Reader<msg::SceneState>>(*participant, topic::kSceneState, profile::kState);
    forces_p = std::make_unique<Reader<msg::ContactForces>>(*participant, topic::kContactForces, profile::kStreamLive);
    status_p = std::make_unique<Reader<msg::ServiceStatus>>(*participant, topic::kServiceStatus, profile::kStatus);
  } catch (const std::exception& e) {
    participant.reset();
    cli.fail(e.what());
  }
  server->setRoute("/mode.json", "application/json",
                   shared(json{{"mode", "live"}, {"domain", dopt.domain}, {"synthetic", synthetic_hand >= 0 ? json(synthetic_hand) : json(nullptr)}}.dump()));
  // Page commands for the synthetic hand arrive on the server thread: the newest offset is kept.
  std::mutex synthetic_mutex;
  Vec3 synthetic_offset = Vec3::Zero();
  std::uint64_t synthetic_commands = 0, synthetic_rejected = 0;
  server->onClientPublish([&](const ClientPublish& c) {
    int h = -1;
    Vec3 off;
    std::string why;
    std::lock_guard<std::mutex> lock(synthetic_mutex);
    if (synthetic_hand < 0 || !parseSyntheticCommand(c.payload, &h, &off, &why) || h != synthetic_hand) {
      ++synthetic_rejected;
      return;
    }
    ++synthetic_commands;
    synthetic_offset = off;
  });
  server->start();
  std::printf("viewer: http://%s:%d/\n", bind.c_str(), server->port());
  std::fflush(stdout);
  std::fprintf(stderr, "viewer: live on DDS domain %d (profiles %s)\n", dopt.domain, participant->profilesFile().c_str());

  const std::uint32_t ch_state = 1, ch_target = 2, ch_desc = 3, ch_scene = 4, ch_forces = 5, ch_status = 6, ch_stats = 7;
  msg::HandState hs;
  msg::HandTarget ht;
  msg::SceneDescription sd;
  msg::SceneState ss;
  msg::ContactForces cf;
  msg::ServiceStatus st;
  std::uint64_t n_state = 0, n_target = 0, n_scene = 0, n_forces = 0, n_status = 0, n_desc = 0, n_bad = 0;

  // The scene, loaded off the DDS thread when a SceneDescription names a new file: its meshes are
  // served to the page and it gives the penetration figure of every received hand.
  std::unique_ptr<Scene> scene;
  std::unique_ptr<CollisionWorld> world;
  std::string scene_loaded_file;
  int generation = 0;
  std::future<LoadedScene> loading;
  msg::SceneDescription pending_desc;
  bool have_pending_desc = false;

  auto elapsed_since = [](std::chrono::steady_clock::time_point t) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
  };
  const std::uint64_t synthetic_run = static_cast<std::uint64_t>(svc::nowNs());
  std::uint64_t synthetic_frame = 0;
  auto next_synthetic = std::chrono::steady_clock::now();
  msg::HandTarget synthetic_out;
  auto last_print = std::chrono::steady_clock::now();
  auto last_stats = last_print;
  std::uint64_t printed_state = 0;
  while (!stopRequested()) {
    participant->waitForData(std::min(std::chrono::steady_clock::now() + std::chrono::milliseconds(50),
                                      synthetic_p ? next_synthetic : std::chrono::steady_clock::time_point::max()));
    if (synthetic_p && std::chrono::steady_clock::now() >= next_synthetic) {
      next_synthetic += std::chrono::duration_cast<std::chrono::steady_clock::duration>(std::chrono::duration<double>(1.0 / synthetic_rate));
      if (next_synthetic < std::chrono::steady_clock::now()) next_synthetic = std::chrono::steady_clock::now();
      Pose X = synthetic_start;
      {
        std::lock_guard<std::mutex> lock(synthetic_mutex);
        X.p += synthetic_offset;
      }
      syntheticTarget(synthetic_model, X, static_cast<std::uint32_t>(synthetic_hand), synthetic, synthetic_run, ++synthetic_frame,
                      svc::nowNs(), &synthetic_out);
      synthetic_p->write(synthetic_out);
    }
    while (descriptions_p->take(sd)) {
      ++n_desc;
      pending_desc = sd;
      have_pending_desc = true;
    }
    if (have_pending_desc && !loading.valid()) {
      const std::string file = pending_desc.file().to_string();
      if (file != scene_loaded_file) {
        loading = std::async(std::launch::async, [file] {
          LoadedScene l;
          l.file = file;
          try {
            l.scene = std::make_unique<Scene>(loadScene(file));
          } catch (const std::exception& e) {
            l.error = e.what();
          }
          return l;
        });
      } else {
        server->publish(ch_desc, "", sceneDescriptionJson(pending_desc, svc::nowNs(), std::to_string(generation)).dump(),
                        static_cast<std::uint64_t>(svc::nowNs()));
        have_pending_desc = false;
      }
    }
    if (loading.valid() && loading.wait_for(std::chrono::seconds(0)) == std::future_status::ready) {
      LoadedScene l = loading.get();
      ++generation;
      world.reset();
      scene = std::move(l.scene);
      scene_loaded_file = l.file;
      std::string gen = std::to_string(generation);
      if (scene) {
        world = std::make_unique<CollisionWorld>(*scene);
        serveMeshes(*server, *scene, gen, display_triangles);
        std::fprintf(stderr, "viewer: scene '%s' loaded from %s (%zu objects)\n", scene->name.c_str(), l.file.c_str(), scene->objects.size());
      } else {
        gen = "";  // the page draws boxes at the object poses
        std::fprintf(stderr, "viewer: cannot load the scene the SceneDescription names (%s); drawing placeholders\n", l.error.c_str());
      }
      server->clearLatched(ch_desc);
      server->publish(ch_desc, "", sceneDescriptionJson(pending_desc, svc::nowNs(), gen).dump(), static_cast<std::uint64_t>(svc::nowNs()));
      have_pending_desc = false;
    }
    while (scenes_p->take(ss)) {
      ++n_scene;
      const std::int64_t now = svc::nowNs();
      if (world)
        for (const msg::ObjectState& o : ss.objects())
          if (o.index() >= 0 && o.index() < world->objectCount()) world->setObjectPose(o.index(), svc::fromWire(o.pose()));
      server->publish(ch_scene, "", sceneStateJson(ss, now).dump(), static_cast<std::uint64_t>(now));
    }
    while (states_p->take(hs)) {
      ++n_state;
      const std::int64_t now = svc::nowNs();
      double pen = -1.0;
      if (world && hs.started()) {
        pen = 0.0;
        for (std::size_t b = 0; b < hs.poses().size() && b < hs.shapes().size(); ++b) {
          const msg::BodyShape& w = hs.shapes()[b];
          if (w.type() > 2) continue;
          Shape s;
          s.type = static_cast<ShapeType>(w.type());
          s.radius = w.radius();
          s.half_length = w.half_length();
          s.half_extents = Vec3(w.half_extents()[0], w.half_extents()[1], w.half_extents()[2]);
          const Pose X = svc::fromWire(hs.poses()[b]);
          if (!X.p.allFinite() || !X.q.coeffs().allFinite()) continue;
          pen = std::max(pen, world->penetration(s, X));
        }
      }
      server->publish(ch_state, std::to_string(hs.hand()), handStateJson(hs, now, pen).dump(), static_cast<std::uint64_t>(now));
    }
    while (targets_p->take(ht)) {
      ++n_target;
      const std::int64_t now = svc::nowNs();
      server->publish(ch_target, std::to_string(ht.hand()), handTargetJson(ht, now).dump(), static_cast<std::uint64_t>(now));
    }
    while (forces_p->take(cf)) {
      ++n_forces;
      const std::int64_t now = svc::nowNs();
      server->publish(ch_forces, "", contactForcesJson(cf, now).dump(), static_cast<std::uint64_t>(now));
    }
    while (status_p->take(st)) {
      ++n_status;
      const std::int64_t now = svc::nowNs();
      server->publish(ch_status, st.service().to_string(), serviceStatusJson(st, now).dump(), static_cast<std::uint64_t>(now));
    }
    n_bad = states_p->rejected() + targets_p->rejected() + descriptions_p->rejected() + scenes_p->rejected() + forces_p->rejected() +
            status_p->rejected();
    if (elapsed_since(last_stats) >= 0.5) {
      last_stats = std::chrono::steady_clock::now();
      const Hub::Stats s = server->stats();
      json clients = json::array();
      for (const auto& c : s.per_client) clients.push_back({{"id", c.id}, {"sent", c.sent}, {"dropped", c.dropped}, {"superseded", c.superseded}, {"waiting", c.waiting}, {"rejected", c.rejected}});
      const std::int64_t now = svc::nowNs();
      server->publish(ch_stats, "",
                      json{{"recv_ns", now},
                           {"received", {{"hand_state", n_state}, {"hand_target", n_target}, {"scene_state", n_scene},
                                         {"contact_forces", n_forces}, {"service_status", n_status}, {"scene_description", n_desc},
                                         {"rejected", n_bad}}},
                           {"clients", s.clients},
                           {"dropped", s.dropped},
                           {"superseded", s.superseded},
                           {"inbox_dropped", server->inboxDropped()},
                           {"per_client", clients}}
                          .dump(),
                      static_cast<std::uint64_t>(now));
    }
    if (!quiet && elapsed_since(last_print) >= 1.0) {
      const Hub::Stats s = server->stats();
      std::fprintf(stderr, "viewer: hand states %llu (+%llu), browsers %d, dropped %llu\n", static_cast<unsigned long long>(n_state),
                   static_cast<unsigned long long>(n_state - printed_state), s.clients, static_cast<unsigned long long>(s.dropped));
      printed_state = n_state;
      last_print = std::chrono::steady_clock::now();
    }
  }
  if (loading.valid()) loading.wait();
  states_p.reset();
  targets_p.reset();
  descriptions_p.reset();
  scenes_p.reset();
  forces_p.reset();
  status_p.reset();
  synthetic_p.reset();
  participant.reset();
  server->stop();
  const Hub::Stats s = server->stats();
  std::fprintf(stderr,
               "viewer: stopped; received hand states %llu, targets %llu, scene states %llu, forces %llu, status %llu, rejected %llu; "
               "browsers %llu (refused %llu), messages sent %llu, dropped for slow browsers %llu, inbox dropped %llu, bad client "
               "messages %llu\n",
               static_cast<unsigned long long>(n_state), static_cast<unsigned long long>(n_target), static_cast<unsigned long long>(n_scene),
               static_cast<unsigned long long>(n_forces), static_cast<unsigned long long>(n_status), static_cast<unsigned long long>(n_bad),
               static_cast<unsigned long long>(s.opened), static_cast<unsigned long long>(s.refused), static_cast<unsigned long long>(s.sent),
               static_cast<unsigned long long>(s.dropped), static_cast<unsigned long long>(server->inboxDropped()),
               static_cast<unsigned long long>(s.rejected));
  if (server->httpRefused() + server->pingsUnanswered() + server->overflowClosed() + server->oldProtocolRefused() + server->badKeyRefused() > 0)
    std::fprintf(stderr,
                 "viewer: network abuse: HTTP requests refused while %d responses were in flight %llu, pings unanswered (queue full) "
                 "%llu, connections closed for not reading %llu, pre-RFC 6455 handshakes refused %llu, bad Sec-WebSocket-Key %llu\n",
                 Server::kMaxHttpInFlight, static_cast<unsigned long long>(server->httpRefused()),
                 static_cast<unsigned long long>(server->pingsUnanswered()), static_cast<unsigned long long>(server->overflowClosed()),
                 static_cast<unsigned long long>(server->oldProtocolRefused()), static_cast<unsigned long long>(server->badKeyRefused()));
  if (synthetic_hand >= 0)
    std::fprintf(stderr, "viewer: synthetic hand '%s': %llu targets published, %llu page commands (%llu rejected)\n", synthetic.c_str(),
                 static_cast<unsigned long long>(synthetic_frame), static_cast<unsigned long long>(synthetic_commands),
                 static_cast<unsigned long long>(synthetic_rejected));
  return 0;
}
