// The only translation unit that includes Fast DDS headers (see dds.h).
#include "dds/dds.h"

#include <tinyxml2.h>

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <cstdlib>
#include <deque>
#include <filesystem>
#include <map>
#include <mutex>
#include <random>
#include <set>
#include <utility>

#include <fastdds/dds/domain/DomainParticipant.hpp>
#include <fastdds/dds/domain/DomainParticipantFactory.hpp>
#include <fastdds/dds/domain/qos/DomainParticipantQos.hpp>
#include <fastdds/dds/log/Log.hpp>
#include <fastdds/dds/publisher/DataWriter.hpp>
#include <fastdds/dds/publisher/Publisher.hpp>
#include <fastdds/dds/publisher/qos/DataWriterQos.hpp>
#include <fastdds/dds/subscriber/DataReader.hpp>
#include <fastdds/dds/subscriber/DataReaderListener.hpp>
#include <fastdds/dds/subscriber/SampleInfo.hpp>
#include <fastdds/dds/subscriber/Subscriber.hpp>
#include <fastdds/dds/subscriber/qos/DataReaderQos.hpp>
#include <fastdds/dds/topic/Topic.hpp>
#include <fastdds/dds/topic/TypeSupport.hpp>
#include <fastdds/rtps/transport/TCPv4TransportDescriptor.h>
#include <fastdds/rtps/transport/TCPv6TransportDescriptor.h>
#include <fastdds/rtps/transport/UDPv4TransportDescriptor.h>
#include <fastdds/rtps/transport/UDPv6TransportDescriptor.h>
#include <fastdds/rtps/transport/shared_mem/SharedMemTransportDescriptor.h>
#include <fastdds/rtps/transport/ChainingTransport.h>
#include <fastdds/rtps/transport/ChainingTransportDescriptor.h>
#include <fastrtps/attributes/ParticipantAttributes.h>
#include <fastrtps/attributes/PublisherAttributes.h>
#include <fastrtps/attributes/SubscriberAttributes.h>
#include <fastrtps/utils/IPLocator.h>
#include <fastrtps/xmlparser/XMLParser.h>
#include <fastrtps/xmlparser/XMLProfileManager.h>
#include <fastrtps/xmlparser/XMLTree.h>

#include "godhandPubSubTypes.h"  // generated TopicDataTypes (Fast DDS API): this file only
#include "godhand_bounds.h"      // generated from the IDL by wire_bounds.cmake: within(sample)

#ifndef GODHAND_DEFAULT_PROFILES
#error "GODHAND_DEFAULT_PROFILES (the shipped profiles file) must be defined by the build"
#endif

namespace godhand::dds {

namespace fdds = eprosima::fastdds::dds;
namespace xml = eprosima::fastrtps::xmlparser;
using eprosima::fastrtps::types::ReturnCode_t;

namespace {

const char* const kPrefix = "godhand::dds: ";

// ---------------------------------------------------------------------------------------------
// Fast DDS reports XML and entity errors only to its log (asynchronously). A consumer that keeps
// the recent errors lets a DdsError quote the one that explains a failure. The default console
// consumer stays registered. The buffer is never destroyed (the log thread may outlive statics).
struct ErrorLog {
  std::mutex mutex;
  std::uint64_t count = 0;                               // errors seen so far
  std::deque<std::pair<std::uint64_t, std::string>> recent;  // (index, "category: message")
};

ErrorLog& errorLog() {
  static ErrorLog* log = new ErrorLog;
  return *log;
}

class ErrorCapture : public fdds::LogConsumer {
 public:
  void Consume(const fdds::Log::Entry& entry) override {
    if (entry.kind != fdds::Log::Kind::Error) return;
    ErrorLog& log = errorLog();
    std::lock_guard<std::mutex> lock(log.mutex);
    std::string text = entry.message;
    std::replace(text.begin(), text.end(), '\n', ' ');
    if (entry.context.category != nullptr) text = std::string(entry.context.category) + ": " + text;
    log.recent.emplace_back(log.count++, std::move(text));
    while (log.recent.size() > 64) log.recent.pop_front();
  }
};

std::uint64_t errorMark() {
  static std::once_flag once;
  std::call_once(once, [] { fdds::Log::RegisterConsumer(std::unique_ptr<fdds::LogConsumer>(new ErrorCapture)); });
  fdds::Log::Flush();
  ErrorLog& log = errorLog();
  std::lock_guard<std::mutex> lock(log.mutex);
  return log.count;
}

// The Fast DDS errors logged since `mark`, most specific first ("Error parsing 'x'" and
// "Problem loading" are consequences: listed last), as ": a | b" (at most 3).
std::string errorsSince(std::uint64_t mark) {
  fdds::Log::Flush();
  ErrorLog& log = errorLog();
  std::lock_guard<std::mutex> lock(log.mutex);
  std::vector<std::string> first, last;
  for (const auto& e : log.recent) {
    if (e.first < mark) continue;
    const bool consequence = e.second.find("Error parsing") != std::string::npos ||
                             e.second.find("Problem loading") != std::string::npos ||
                             e.second.find("Error loading") != std::string::npos;
    (consequence ? last : first).push_back(e.second);
  }
  first.insert(first.end(), last.begin(), last.end());
  if (first.empty()) return " (no reason given: see the Fast DDS log)";
  std::string out = ": ";
  for (std::size_t i = 0; i < first.size() && i < 3; ++i) out += (i ? " | " : "") + first[i];
  return out;
}

std::string inQuotes(const std::string& s) { return "'" + s + "'"; }

std::string joined(const std::vector<std::string>& v) {
  std::string out;
  for (const auto& s : v) out += (out.empty() ? "" : ", ") + s;
  return out.empty() ? "none" : out;
}

// ---------------------------------------------------------------------------------------------
// Profiles files. Fast DDS keeps profile names and transport ids in process-wide registries
// (the first registration of a name wins, later ones are refused). We keep, per file, what it
// declares, so that errors name the file and clashes are found before they silently pick
// another file's profile.
struct FileProfiles {
  std::vector<std::string> participants, writers, readers, transports;
};

struct ProfilesRegistry {
  std::mutex mutex;
  std::map<std::string, std::string> loaded;   // path -> "" (ok) or the error message
  std::map<std::string, std::string> checked;  // path -> "" (ok) or the error message
  std::map<std::string, FileProfiles> files;   // path -> what it declares (loaded ok)
  int check_serial = 0;
};

ProfilesRegistry& registry() {
  static ProfilesRegistry* r = new ProfilesRegistry;
  return *r;
}

bool contains(const std::vector<std::string>& v, const std::string& s) {
  return std::find(v.begin(), v.end(), s) != v.end();
}

// Parses the file with tinyxml2 (what Fast DDS uses) for a precise syntax error and the list of
// profiles; `doc` keeps the parsed document.
FileProfiles scanProfiles(const std::string& path, tinyxml2::XMLDocument& doc) {
  std::error_code ec;
  if (path.empty()) throw DdsError(std::string(kPrefix) + "no DDS profiles file given");
  if (!std::filesystem::exists(path, ec))
    throw DdsError(std::string(kPrefix) + "DDS profiles file " + inQuotes(path) + " does not exist");
  if (!std::filesystem::is_regular_file(path, ec))
    throw DdsError(std::string(kPrefix) + "DDS profiles file " + inQuotes(path) + " is not a regular file");
  const tinyxml2::XMLError err = doc.LoadFile(path.c_str());
  if (err != tinyxml2::XML_SUCCESS) {
    // ErrorStr(): "Error=XML_ERROR_MISMATCHED_ELEMENT ErrorID=14 (0xe) Line number=5: XMLElement name=rtps".
    std::string what = tinyxml2::XMLDocument::ErrorIDToName(err);
    const std::string str = doc.ErrorStr() != nullptr ? doc.ErrorStr() : "";
    const std::size_t detail = str.find(": ", str.find("Line number="));
    if (str.find("Line number=") != std::string::npos && detail != std::string::npos) what += str.substr(detail);
    std::replace(what.begin(), what.end(), '\n', ' ');
    if (err == tinyxml2::XML_ERROR_FILE_COULD_NOT_BE_OPENED || err == tinyxml2::XML_ERROR_FILE_READ_ERROR)
      throw DdsError(std::string(kPrefix) + "cannot read DDS profiles file " + inQuotes(path) + ": " + what);
    throw DdsError(std::string(kPrefix) + "DDS profiles file " + inQuotes(path) + " is not valid XML (line " +
                   std::to_string(doc.ErrorLineNum()) + "): " + what);
  }
  tinyxml2::XMLElement* root = doc.RootElement();
  tinyxml2::XMLElement* profiles = nullptr;
  if (root != nullptr && std::string(root->Name()) == "profiles") profiles = root;
  if (root != nullptr && std::string(root->Name()) == "dds") profiles = root->FirstChildElement("profiles");
  if (profiles == nullptr)
    throw DdsError(std::string(kPrefix) + "DDS profiles file " + inQuotes(path) +
                   " has no <profiles> element (a Fast DDS XML profiles file starts with <profiles> or <dds><profiles>)");
  FileProfiles out;
  for (tinyxml2::XMLElement* e = profiles->FirstChildElement(); e != nullptr; e = e->NextSiblingElement()) {
    const std::string tag = e->Name();
    const char* name = e->Attribute("profile_name");
    if (tag == "participant" && name) out.participants.push_back(name);
    if ((tag == "data_writer" || tag == "publisher") && name) out.writers.push_back(name);
    if ((tag == "data_reader" || tag == "subscriber") && name) out.readers.push_back(name);
    if (tag == "transport_descriptors") {
      for (tinyxml2::XMLElement* t = e->FirstChildElement("transport_descriptor"); t != nullptr;
           t = t->NextSiblingElement("transport_descriptor")) {
        tinyxml2::XMLElement* id = t->FirstChildElement("transport_id");
        if (id != nullptr && id->GetText() != nullptr) out.transports.push_back(id->GetText());
      }
    }
  }
  return out;
}

// The name under which Fast DDS loaded `path` by itself, if it did: $FASTRTPS_DEFAULT_PROFILES_FILE
// or ./DEFAULT_FASTRTPS_PROFILES.xml naming the same file. "" otherwise.
std::string loadedByFastDds(const std::string& path) {
  const char* env = std::getenv("FASTRTPS_DEFAULT_PROFILES_FILE");
  const char* skip = std::getenv("SKIP_DEFAULT_XML_FILE");
  std::vector<std::string> candidates;
  if (env != nullptr && *env != '\0') candidates.push_back(env);
  if (skip == nullptr || skip[0] != '1') candidates.push_back("DEFAULT_FASTRTPS_PROFILES.xml");
  for (const auto& c : candidates) {
    std::error_code ec;
    if (c == path || std::filesystem::equivalent(c, path, ec)) return c;
  }
  return "";
}

std::string loadProfilesLocked(ProfilesRegistry& reg, const std::string& path) {
  tinyxml2::XMLDocument doc;
  FileProfiles declared;
  try {
    declared = scanProfiles(path, doc);
  } catch (const DdsError& e) {
    return e.what();
  }
  const std::string file = "DDS profiles file " + inQuotes(path);
  // The files Fast DDS loads by itself ($FASTRTPS_DEFAULT_PROFILES_FILE, ./DEFAULT_FASTRTPS_PROFILES.xml)
  // go first, so that a clash with them is found now.
  const std::uint64_t mark = errorMark();
  fdds::DomainParticipantFactory::get_instance()->load_profiles();
  eprosima::fastrtps::ParticipantAttributes pa;
  eprosima::fastrtps::PublisherAttributes wa;
  eprosima::fastrtps::SubscriberAttributes ra;
  // `what` (of kind `list`) is already registered: name the file it came from when we loaded it.
  auto clash = [&](const std::string& what, const std::string& name,
                   std::vector<std::string> FileProfiles::*list) {
    std::string from = "another profiles file ($FASTRTPS_DEFAULT_PROFILES_FILE or ./DEFAULT_FASTRTPS_PROFILES.xml?)";
    for (const auto& f : reg.files)
      if (contains(f.second.*list, name)) from = inQuotes(f.first);
    return std::string(kPrefix) + file + ": " + what + " " + inQuotes(name) +
           " is already registered in this process from " + from +
           " (Fast DDS keeps profile names and transport ids process-wide: use one godhand profiles file per process)";
  };
  // A file Fast DDS loaded itself is registered already (under that name): no clash with itself.
  const std::string alias = loadedByFastDds(path);
  if (!alias.empty()) {
    const xml::XMLP_ret ret = xml::XMLProfileManager::loadXMLFile(alias);  // "already parsed" when it went well
    if (ret != xml::XMLP_ret::XML_OK)
      return std::string(kPrefix) + file + ": Fast DDS rejected it" + errorsSince(mark);
    reg.files[path] = std::move(declared);
    return "";
  }
  for (const auto& n : declared.participants)
    if (xml::XMLProfileManager::fillParticipantAttributes(n, pa, false) == xml::XMLP_ret::XML_OK)
      return clash("participant profile", n, &FileProfiles::participants);
  for (const auto& n : declared.writers)
    if (xml::XMLProfileManager::fillPublisherAttributes(n, wa, false) == xml::XMLP_ret::XML_OK)
      return clash("data_writer profile", n, &FileProfiles::writers);
  for (const auto& n : declared.readers)
    if (xml::XMLProfileManager::fillSubscriberAttributes(n, ra, false) == xml::XMLP_ret::XML_OK)
      return clash("data_reader profile", n, &FileProfiles::readers);
  for (const auto& n : declared.transports)
    if (xml::XMLProfileManager::getTransportById(n) != nullptr)
      return clash("transport id", n, &FileProfiles::transports);
  const xml::XMLP_ret ret = xml::XMLProfileManager::loadXMLFile(path);
  if (ret != xml::XMLP_ret::XML_OK)
    return std::string(kPrefix) + file + ": Fast DDS rejected it" +
           (ret == xml::XMLP_ret::XML_NOK ? " in part (some profiles were not registered)" : "") +
           errorsSince(mark);
  reg.files[path] = std::move(declared);
  return "";
}

// ---------------------------------------------------------------------------------------------
// Locators and QoS as strings / QosInfo.
using eprosima::fastrtps::rtps::IPLocator;
using eprosima::fastrtps::rtps::Locator_t;

std::string locatorString(const Locator_t& l) {
  std::string addr;
  switch (l.kind) {
    case LOCATOR_KIND_UDPv4:
    case LOCATOR_KIND_TCPv4:
      addr = IPLocator::toIPv4string(l);
      break;
    case LOCATOR_KIND_UDPv6:
    case LOCATOR_KIND_TCPv6:
      addr = "[" + IPLocator::toIPv6string(l) + "]";
      break;
    case LOCATOR_KIND_SHM:
      addr = "shm";
      break;
    default:
      addr = "kind" + std::to_string(l.kind);
  }
  return l.port != 0 ? addr + ":" + std::to_string(l.port) : addr;
}

template <class Qos>
QosInfo qosInfo(const Qos& q) {  // what DataWriterQos and DataReaderQos share
  QosInfo out;
  out.reliable = q.reliability().kind == fdds::RELIABLE_RELIABILITY_QOS;
  out.transient_local = q.durability().kind != fdds::VOLATILE_DURABILITY_QOS;
  out.keep_all = q.history().kind == fdds::KEEP_ALL_HISTORY_QOS;
  out.depth = q.history().depth;
  out.max_samples = q.resource_limits().max_samples;
  return out;
}

QosInfo qosInfo(const fdds::DataWriterQos& q) {
  QosInfo out = qosInfo<fdds::DataWriterQos>(q);
  out.synchronous = q.publish_mode().kind == fdds::SYNCHRONOUS_PUBLISH_MODE;
  return out;
}

// T -> its generated TopicDataType.
template <class T>
struct WireType;
#define GODHAND_WIRE_TYPE(T)             \
  template <>                            \
  struct WireType<msg::T> {              \
    using PubSub = msg::T##PubSubType;   \
  };
GODHAND_WIRE_TYPE(HandTarget)
GODHAND_WIRE_TYPE(HandProposal)
GODHAND_WIRE_TYPE(HandState)
GODHAND_WIRE_TYPE(ContactForces)
GODHAND_WIRE_TYPE(SceneState)
GODHAND_WIRE_TYPE(SceneDescription)
GODHAND_WIRE_TYPE(ServiceStatus)
#undef GODHAND_WIRE_TYPE

}  // namespace

// -------------------------------------------------------------------------------------------------
// Participant

// A Writer's or Reader's Fast DDS entity, so that ~Participant can delete what is left.
struct Endpoint {
  virtual ~Endpoint() = default;
  virtual void release() = 0;  // deletes the entity (idempotent); called with Core::entities held
};

struct Participant::Core {
  std::shared_ptr<fdds::DomainParticipantFactory> factory;  // outlives our participant
  Options options;
  std::string profiles_file;
  fdds::DomainParticipant* participant = nullptr;
  fdds::Publisher* publisher = nullptr;
  fdds::Subscriber* subscriber = nullptr;

  std::mutex entities;  // guards what follows, and entity creation / deletion
  bool closed = false;
  std::map<std::string, fdds::TypeSupport> types;  // by type name
  std::map<std::string, fdds::Topic*> topics;      // by topic name
  std::set<Endpoint*> endpoints;

  // Data-available signal: a counter, so that no notification is lost between take() and wait.
  std::mutex signal_mutex;
  std::condition_variable signal;
  std::uint64_t data_events = 0;
  std::uint64_t seen_events = 0;
  bool woken = false;
  // What the readers' listeners were told (Participant::samplesLost / samplesRejected).
  std::atomic<std::uint64_t> samples_lost{0}, samples_rejected{0};
  std::atomic<std::uint64_t> samples_malformed{0};  // dropped by take(): over an IDL bound or undecodable
  mutable std::mutex losses_mutex;  // guards losses (per topic: lost, rejected)
  std::map<std::pair<std::string, bool>, std::pair<std::uint64_t, std::uint64_t>> losses;  // (topic, newest only)
  void addLosses(const std::string& topic, bool newest_only, std::uint64_t lost, std::uint64_t rejected) {
    samples_lost.fetch_add(lost, std::memory_order_relaxed);
    samples_rejected.fetch_add(rejected, std::memory_order_relaxed);
    std::lock_guard<std::mutex> lock(losses_mutex);
    auto& e = losses[{topic, newest_only}];
    e.first += lost;
    e.second += rejected;
  }

  void notifyData() {
    {
      std::lock_guard<std::mutex> lock(signal_mutex);
      ++data_events;
    }
    signal.notify_all();
  }

  // The topic `name` of this participant with type PubSub (type registered and topic created
  // once). Call with `entities` held.
  template <class PubSub>
  fdds::Topic* topic(const std::string& name) {
    if (closed) throw DdsError(std::string(kPrefix) + "participant is being destroyed");
    fdds::TypeSupport type(new PubSub());
    const std::string type_name = type.get_type_name();
    auto t = topics.find(name);
    if (t != topics.end()) {
      if (t->second->get_type_name() != type_name)
        throw DdsError(std::string(kPrefix) + "topic " + inQuotes(name) + " already has type " +
                       t->second->get_type_name() + " in this participant, not " + type_name);
      return t->second;
    }
    if (types.find(type_name) == types.end()) {
      const std::uint64_t mark = errorMark();
      if (type.register_type(participant) != ReturnCode_t::RETCODE_OK)
        throw DdsError(std::string(kPrefix) + "cannot register type " + type_name + errorsSince(mark));
      types.emplace(type_name, type);
    }
    const std::uint64_t mark = errorMark();
    fdds::Topic* created = participant->create_topic(name, type_name, fdds::TOPIC_QOS_DEFAULT);
    if (created == nullptr)
      throw DdsError(std::string(kPrefix) + "cannot create topic " + inQuotes(name) + " (" + type_name + ")" +
                     errorsSince(mark));
    topics.emplace(name, created);
    return created;
  }

  // The profile must be a data_writer (writer) / data_reader profile known to Fast DDS.
  void requireEndpointProfile(bool writer, const std::string& profile) const {
    bool found = false;
    if (writer) {
      eprosima::fastrtps::PublisherAttributes a;
      found = xml::XMLProfileManager::fillPublisherAttributes(profile, a, false) == xml::XMLP_ret::XML_OK;
    } else {
      eprosima::fastrtps::SubscriberAttributes a;
      found = xml::XMLProfileManager::fillSubscriberAttributes(profile, a, false) == xml::XMLP_ret::XML_OK;
    }
    if (found) return;
    std::vector<std::string> known;
    {
      ProfilesRegistry& reg = registry();
      std::lock_guard<std::mutex> lock(reg.mutex);
      auto f = reg.files.find(profiles_file);
      if (f != reg.files.end()) known = writer ? f->second.writers : f->second.readers;
    }
    throw DdsError(std::string(kPrefix) + "no " + (writer ? "data_writer" : "data_reader") + " profile " +
                   inQuotes(profile) + " in DDS profiles file " + inQuotes(profiles_file) + " (it has: " + joined(known) +
                   ")");
  }
};

std::string Participant::resolveProfiles(const std::string& profiles) {
  if (!profiles.empty()) return profiles;
  const char* env = std::getenv("FASTRTPS_DEFAULT_PROFILES_FILE");
  if (env != nullptr && *env != '\0') return env;
  return GODHAND_DEFAULT_PROFILES;
}

void Participant::loadProfiles(const std::string& path) {
  ProfilesRegistry& reg = registry();
  std::lock_guard<std::mutex> lock(reg.mutex);
  auto it = reg.loaded.find(path);
  if (it == reg.loaded.end()) it = reg.loaded.emplace(path, loadProfilesLocked(reg, path)).first;
  if (!it->second.empty()) throw DdsError(it->second);
}

void Participant::checkProfiles(const std::string& path) {
  ProfilesRegistry& reg = registry();
  std::lock_guard<std::mutex> lock(reg.mutex);
  auto loaded = reg.loaded.find(path);
  if (loaded != reg.loaded.end() && loaded->second.empty()) return;  // loaded fine: parsed fine
  auto it = reg.checked.find(path);
  if (it == reg.checked.end()) {
    std::string error;
    try {
      tinyxml2::XMLDocument doc;
      scanProfiles(path, doc);
      // Fast DDS's parser registers transport descriptors by id as it parses (process-wide; a
      // second registration of an id fails). Parse a copy whose transport ids are made unique,
      // so that this check leaves the file loadable (and checkable) later.
      const std::string tag = "godhand_check" + std::to_string(++reg.check_serial) + "_";
      std::vector<tinyxml2::XMLElement*> stack{doc.RootElement()};
      while (!stack.empty()) {
        tinyxml2::XMLElement* e = stack.back();
        stack.pop_back();
        if (std::string(e->Name()) == "transport_id" && e->GetText() != nullptr)
          e->SetText((tag + e->GetText()).c_str());
        for (tinyxml2::XMLElement* c = e->FirstChildElement(); c != nullptr; c = c->NextSiblingElement())
          stack.push_back(c);
      }
      tinyxml2::XMLPrinter printer;
      doc.Print(&printer);
      const std::uint64_t mark = errorMark();
      xml::up_base_node_t root;
      const xml::XMLP_ret ret =
          xml::XMLParser::loadXML(printer.CStr(), static_cast<std::size_t>(printer.CStrSize() - 1), root);
      if (ret != xml::XMLP_ret::XML_OK || !root)
        error = std::string(kPrefix) + "DDS profiles file " + inQuotes(path) + ": Fast DDS rejected it" + errorsSince(mark);
    } catch (const DdsError& e) {
      error = e.what();
    }
    it = reg.checked.emplace(path, error).first;
  }
  if (!it->second.empty()) throw DdsError(it->second);
}

namespace {

// Options::drop_data_percent resolved: the option, or the environment's where it is -1.
int dropDataPercent(int option) {
  constexpr const char* kEnv = "GODHAND_DDS_DROP_DATA_PERCENT";
  if (option >= 0) {
    if (option > 100) throw DdsError(std::string(kPrefix) + "drop_data_percent " + std::to_string(option) + " is out of range (0..100)");
    return option;
  }
  const char* env = std::getenv(kEnv);
  if (env == nullptr || *env == '\0') return 0;
  char* end = nullptr;
  const long v = std::strtol(env, &end, 10);
  if (end == env || *end != '\0' || v < 0 || v > 100)
    throw DdsError(std::string(kPrefix) + kEnv + "=" + inQuotes(env) + " is not a percentage (an integer 0..100)");
  return static_cast<int>(v);
}

// Fault injection (Options::drop_data_percent): a transport over the profile's UDPv4 one that
// loses `percent` % of the datagrams carrying a user writer's DATA or DATA_FRAG submessage, as a
// lossy network would, and sends everything else (discovery, heartbeats, acknacks, gaps) as it
// is. (Fast DDS's own test_UDPv4 transport does the same by submessage, but in this build a
// scene service on it was never matched by the services started after it; plain UDPv4 was.)
struct LossyDescriptor;
class LossyTransport : public eprosima::fastdds::rtps::ChainingTransport {
 public:
  explicit LossyTransport(const LossyDescriptor& d);
  eprosima::fastdds::rtps::TransportDescriptorInterface* get_configuration() override;
  bool send(eprosima::fastrtps::rtps::SenderResource* low, const eprosima::fastrtps::rtps::octet* buffer,
            std::uint32_t size, eprosima::fastrtps::rtps::LocatorsIterator* begin,
            eprosima::fastrtps::rtps::LocatorsIterator* end,
            const std::chrono::steady_clock::time_point& timeout) override {
    if (carriesUserData(buffer, size) && lose()) return true;  // lost on the way: the sender cannot tell
    return low->send(buffer, size, begin, end, timeout);
  }
  void receive(eprosima::fastdds::rtps::TransportReceiverInterface* next, const eprosima::fastrtps::rtps::octet* buffer,
               std::uint32_t size, const eprosima::fastrtps::rtps::Locator_t& local,
               const eprosima::fastrtps::rtps::Locator_t& remote) override {
    next->OnDataReceived(buffer, size, local, remote);
  }

 private:
  // An RTPS message (header: "RTPS", version, vendor, GUID prefix: 20 bytes) with a DATA (0x15)
  // or DATA_FRAG (0x16) submessage whose writer is not a built-in entity (entity kind 0xC0 bits
  // clear). Submessage header: id, flags (bit 0: little endian), length (0: to the end).
  static bool carriesUserData(const eprosima::fastrtps::rtps::octet* b, std::uint32_t size) {
    if (size < 20 || b[0] != 'R' || b[1] != 'T' || b[2] != 'P' || b[3] != 'S') return false;
    std::uint32_t pos = 20;
    while (pos + 4 <= size) {
      const unsigned id = b[pos], flags = b[pos + 1];
      const std::uint32_t len = (flags & 1u) ? (b[pos + 2] | (b[pos + 3] << 8)) : ((b[pos + 2] << 8) | b[pos + 3]);
      const std::uint32_t body = pos + 4;
      // DATA / DATA_FRAG body: extra flags (2), octets to inline QoS (2), reader id (4), writer id (4).
      if ((id == 0x15 || id == 0x16) && body + 12 <= size && (b[body + 11] & 0xC0u) == 0) return true;
      if (len == 0) break;
      pos = body + len;
    }
    return false;
  }
  bool lose() {
    std::lock_guard<std::mutex> lock(mutex_);
    return std::uniform_int_distribution<int>(0, 99)(rng_) < percent_;
  }

  std::unique_ptr<LossyDescriptor> descriptor_;
  int percent_;
  std::mutex mutex_;
  std::mt19937 rng_;
};

struct LossyDescriptor : eprosima::fastdds::rtps::ChainingTransportDescriptor {
  LossyDescriptor(std::shared_ptr<eprosima::fastdds::rtps::TransportDescriptorInterface> low, int lose_percent)
      : ChainingTransportDescriptor(std::move(low)), percent(lose_percent) {}
  eprosima::fastdds::rtps::TransportInterface* create_transport() const override { return new LossyTransport(*this); }
  int percent;
};

LossyTransport::LossyTransport(const LossyDescriptor& d)
    : ChainingTransport(d), descriptor_(std::make_unique<LossyDescriptor>(d)), percent_(d.percent), rng_(std::random_device{}()) {}
eprosima::fastdds::rtps::TransportDescriptorInterface* LossyTransport::get_configuration() { return descriptor_.get(); }

// The profile's UDPv4 transports, each under a LossyTransport; the other transports (shared
// memory) left out, so that same-host traffic takes the lossy path too.
void lossyTransports(fdds::DomainParticipantQos& qos, int percent, const std::string& file, const std::string& profile) {
  std::vector<std::shared_ptr<eprosima::fastdds::rtps::TransportDescriptorInterface>> lossy;
  for (const auto& d : qos.transport().user_transports)
    if (std::dynamic_pointer_cast<eprosima::fastdds::rtps::UDPv4TransportDescriptor>(d))
      lossy.push_back(std::make_shared<LossyDescriptor>(d, percent));
  if (lossy.empty())
    throw DdsError(std::string(kPrefix) + "dropping DATA messages needs a UDPv4 user transport; participant profile " +
                   inQuotes(profile) + " of " + inQuotes(file) + " has none");
  qos.transport().user_transports = lossy;
  qos.transport().use_builtin_transports = false;
}

}  // namespace

Participant::Participant(const Options& options) : core_(std::make_shared<Core>()) {
  Core& c = *core_;
  c.options = options;
  if (options.domain < 0 || options.domain > 232)
    throw DdsError(std::string(kPrefix) + "DDS domain " + std::to_string(options.domain) +
                   " is out of range (0..232)");
  c.profiles_file = resolveProfiles(options.profiles);
  loadProfiles(c.profiles_file);
  {
    ProfilesRegistry& reg = registry();
    std::lock_guard<std::mutex> lock(reg.mutex);
    const FileProfiles& declared = reg.files[c.profiles_file];
    if (!contains(declared.participants, options.participant_profile))
      throw DdsError(std::string(kPrefix) + "no participant profile " + inQuotes(options.participant_profile) +
                     " in DDS profiles file " + inQuotes(c.profiles_file) + " (it has: " + joined(declared.participants) +
                     ")");
  }
  c.factory = fdds::DomainParticipantFactory::get_shared_instance();
  // create_participant_with_profile() cannot set the participant name; this is what it does
  // (profile -> QoS over the factory's default), plus the name.
  fdds::DomainParticipantQos qos;
  if (c.factory->get_participant_qos_from_profile(options.participant_profile, qos) != ReturnCode_t::RETCODE_OK)
    throw DdsError(std::string(kPrefix) + "Fast DDS has no participant profile " +
                   inQuotes(options.participant_profile) + " (from " + inQuotes(c.profiles_file) + ")");
  if (!options.name.empty()) qos.name(options.name);
  const int drop = dropDataPercent(options.drop_data_percent);
  if (drop > 0) lossyTransports(qos, drop, c.profiles_file, options.participant_profile);
  const std::uint64_t mark = errorMark();
  c.participant = c.factory->create_participant(options.domain, qos, nullptr, fdds::StatusMask::none());
  if (c.participant == nullptr)
    throw DdsError(std::string(kPrefix) + "Fast DDS could not create a participant on domain " +
                   std::to_string(options.domain) + " from profile " + inQuotes(options.participant_profile) + " of " +
                   inQuotes(c.profiles_file) + errorsSince(mark));
  c.publisher = c.participant->create_publisher(fdds::PUBLISHER_QOS_DEFAULT, nullptr, fdds::StatusMask::none());
  c.subscriber = c.participant->create_subscriber(fdds::SUBSCRIBER_QOS_DEFAULT, nullptr, fdds::StatusMask::none());
  if (c.publisher == nullptr || c.subscriber == nullptr) {
    c.participant->delete_contained_entities();
    c.factory->delete_participant(c.participant);
    throw DdsError(std::string(kPrefix) + "Fast DDS could not create a publisher / subscriber" + errorsSince(mark));
  }
}

Participant::~Participant() {
  Core& c = *core_;
  {
    std::lock_guard<std::mutex> lock(c.entities);
    for (Endpoint* e : c.endpoints) e->release();  // Writers / Readers the user did not destroy first
    c.endpoints.clear();
    c.closed = true;
    if (c.participant != nullptr) {
      c.participant->delete_contained_entities();  // publisher, subscriber, topics
      c.factory->delete_participant(c.participant);
      c.participant = nullptr;
      c.publisher = nullptr;
      c.subscriber = nullptr;
      c.topics.clear();
    }
  }
  wake();
}

int Participant::domain() const { return core_->options.domain; }
std::uint64_t Participant::samplesLost() const { return core_->samples_lost.load(std::memory_order_relaxed); }
std::uint64_t Participant::samplesRejected() const { return core_->samples_rejected.load(std::memory_order_relaxed); }
std::uint64_t Participant::samplesMalformed() const { return core_->samples_malformed.load(std::memory_order_relaxed); }
std::vector<Participant::TopicLosses> Participant::lossesByTopic() const {
  std::vector<TopicLosses> out;
  std::lock_guard<std::mutex> lock(core_->losses_mutex);
  for (const auto& e : core_->losses)
    if (e.second.first > 0 || e.second.second > 0)
      out.push_back(TopicLosses{e.first.first, e.second.first, e.second.second, e.first.second});
  return out;
}
const std::string& Participant::profilesFile() const { return core_->profiles_file; }

ParticipantInfo Participant::info() const {
  ParticipantInfo out;
  const fdds::DomainParticipantQos& q = core_->participant->get_qos();
  out.name = q.name().to_string();
  out.builtin_transports = q.transport().use_builtin_transports;
  namespace rtps = eprosima::fastdds::rtps;
  for (const auto& d : q.transport().user_transports) {
    if (dynamic_cast<const rtps::SharedMemTransportDescriptor*>(d.get()) != nullptr) {
      out.transports.push_back("SHM");
    } else if (const auto* u4 = dynamic_cast<const rtps::UDPv4TransportDescriptor*>(d.get())) {
      out.transports.push_back("UDPv4");
      out.udp_whitelist.insert(out.udp_whitelist.end(), u4->interfaceWhiteList.begin(), u4->interfaceWhiteList.end());
    } else if (dynamic_cast<const rtps::UDPv6TransportDescriptor*>(d.get()) != nullptr) {
      out.transports.push_back("UDPv6");
    } else if (dynamic_cast<const rtps::TCPv4TransportDescriptor*>(d.get()) != nullptr) {
      out.transports.push_back("TCPv4");
    } else if (dynamic_cast<const rtps::TCPv6TransportDescriptor*>(d.get()) != nullptr) {
      out.transports.push_back("TCPv6");
    } else {
      out.transports.push_back("other");
    }
  }
  const auto& wire = q.wire_protocol();
  for (const auto& l : wire.builtin.initialPeersList) out.initial_peers.push_back(locatorString(l));
  for (const auto& l : wire.default_unicast_locator_list) out.unicast_locators.push_back(locatorString(l));
  for (const auto& l : wire.builtin.metatrafficUnicastLocatorList) out.unicast_locators.push_back(locatorString(l));
  bool multicast = !wire.default_multicast_locator_list.empty() || !wire.builtin.metatrafficMulticastLocatorList.empty();
  for (const auto& l : wire.default_unicast_locator_list) multicast = multicast || IPLocator::isMulticast(l);
  for (const auto& l : wire.builtin.metatrafficUnicastLocatorList) multicast = multicast || IPLocator::isMulticast(l);
  // With no metatraffic locator at all, Fast DDS adds the multicast discovery locator itself.
  if (wire.builtin.metatrafficUnicastLocatorList.empty() && wire.builtin.metatrafficMulticastLocatorList.empty())
    multicast = true;
  out.multicast_locators = multicast;
  return out;
}

bool Participant::waitForData(std::chrono::steady_clock::time_point deadline) {
  Core& c = *core_;
  std::unique_lock<std::mutex> lock(c.signal_mutex);
  c.signal.wait_until(lock, deadline, [&c] { return c.data_events != c.seen_events || c.woken; });
  const bool data = c.data_events != c.seen_events;
  c.seen_events = c.data_events;
  c.woken = false;
  return data;
}

void Participant::wake() {
  Core& c = *core_;
  {
    std::lock_guard<std::mutex> lock(c.signal_mutex);
    c.woken = true;
  }
  c.signal.notify_all();
}

// -------------------------------------------------------------------------------------------------
// Writer

template <class T>
struct Writer<T>::Impl : Endpoint {
  std::shared_ptr<Participant::Core> core;
  std::string topic;
  std::mutex mutex;  // guards writer (write vs. release)
  fdds::DataWriter* writer = nullptr;
  std::atomic<std::uint64_t> written{0};
  std::atomic<std::uint64_t> failed{0};

  void release() override {
    std::lock_guard<std::mutex> lock(mutex);
    if (writer != nullptr && core->publisher != nullptr) {
      // Fast DDS 2.9.1's ~StatefulWriter hands the history's samples back to their pool one at a
      // time while they are still in the history, and stops the periodic heartbeat only after
      // that; a heartbeat in between (samples unacknowledged) spins for good on the released
      // samples' sequence number 0, and the deletion waits for it (tests/services/test_dds.cc,
      // DdsTeardown). Emptied first, under the writer's mutex, the history is consistent at every
      // heartbeat. (RETCODE_ERROR when there was nothing to remove: nothing to do then.)
      std::size_t removed = 0;
      writer->clear_history(&removed);
      core->publisher->delete_datawriter(writer);
    }
    writer = nullptr;
  }
};

template <class T>
Writer<T>::Writer(Participant& participant, const std::string& topic, const std::string& profile)
    : impl_(new Impl) {
  impl_->core = participant.core_;
  impl_->topic = topic;
  Participant::Core& c = *impl_->core;
  std::lock_guard<std::mutex> lock(c.entities);
  fdds::Topic* t = c.template topic<typename WireType<T>::PubSub>(topic);
  c.requireEndpointProfile(true, profile);
  const std::uint64_t mark = errorMark();
  impl_->writer = c.publisher->create_datawriter_with_profile(t, profile, nullptr, fdds::StatusMask::none());
  if (impl_->writer == nullptr)
    throw DdsError(std::string(kPrefix) + "Fast DDS could not create a writer on " + inQuotes(topic) +
                   " from data_writer profile " + inQuotes(profile) + " of " + inQuotes(c.profiles_file) + errorsSince(mark));
  c.endpoints.insert(impl_.get());
}

template <class T>
Writer<T>::~Writer() {
  Participant::Core& c = *impl_->core;
  std::lock_guard<std::mutex> lock(c.entities);
  c.endpoints.erase(impl_.get());
  impl_->release();
}

template <class T>
bool Writer<T>::write(const T& sample) {
  bool ok = false;
  if (msg::wire_bounds::within(sample)) {  // else: Fast DDS would send it (see wire_bounds.cmake)
    std::lock_guard<std::mutex> lock(impl_->mutex);
    if (impl_->writer != nullptr) {
      try {
        // DataWriter::write takes void*; it does not modify the sample.
        ok = impl_->writer->write(const_cast<T*>(&sample));
      } catch (...) {  // fastcdr exceptions escaping a serializer: a failed write, never a crash
        ok = false;
      }
    }
  }
  (ok ? impl_->written : impl_->failed).fetch_add(1, std::memory_order_relaxed);
  return ok;
}

template <class T>
bool Writer<T>::waitForAcknowledgments(std::chrono::milliseconds timeout) {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  if (impl_->writer == nullptr) return false;
  const long long ms = std::max<long long>(0, timeout.count());
  const eprosima::fastrtps::Duration_t d(static_cast<std::int32_t>(ms / 1000), static_cast<std::uint32_t>((ms % 1000) * 1000000));
  return impl_->writer->wait_for_acknowledgments(d) == ReturnCode_t::RETCODE_OK;
}

template <class T>
int Writer<T>::matched() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  if (impl_->writer == nullptr) return 0;
  fdds::PublicationMatchedStatus status;
  if (impl_->writer->get_publication_matched_status(status) != ReturnCode_t::RETCODE_OK) return 0;
  return status.current_count;
}

template <class T>
QosInfo Writer<T>::qos() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->writer != nullptr ? qosInfo(impl_->writer->get_qos()) : QosInfo{};
}

template <class T>
std::uint64_t Writer<T>::written() const {
  return impl_->written.load(std::memory_order_relaxed);
}
template <class T>
std::uint64_t Writer<T>::failed() const {
  return impl_->failed.load(std::memory_order_relaxed);
}
template <class T>
const std::string& Writer<T>::topic() const {
  return impl_->topic;
}

// -------------------------------------------------------------------------------------------------
// Reader

namespace {
class DataListener : public fdds::DataReaderListener {
 public:
  DataListener(Participant::Core* core, std::string topic, bool newest_only)
      : core_(core), topic_(std::move(topic)), newest_only_(newest_only) {}
  void on_data_available(fdds::DataReader*) override { core_->notifyData(); }
  // (The totals are this reader's, cumulative: their growth goes to the participant's sums, in
  // all and per topic. The callbacks may come from more than one receive thread, hence the lock;
  // they are rare.)
  void on_sample_lost(fdds::DataReader*, const fdds::SampleLostStatus& status) override {
    const std::uint64_t total = status.total_count > 0 ? static_cast<std::uint64_t>(status.total_count) : 0;
    std::lock_guard<std::mutex> lock(mutex_);
    if (total > lost_) core_->addLosses(topic_, newest_only_, total - lost_, 0);
    lost_ = std::max(lost_, total);
  }
  void on_sample_rejected(fdds::DataReader*, const eprosima::fastrtps::SampleRejectedStatus& status) override {
    const std::uint64_t total = status.total_count;
    std::lock_guard<std::mutex> lock(mutex_);
    if (total > rejected_) core_->addLosses(topic_, newest_only_, 0, total - rejected_);
    rejected_ = std::max(rejected_, total);
  }

 private:
  Participant::Core* core_;
  std::string topic_;
  bool newest_only_;  // Participant::TopicLosses::newest_only
  std::mutex mutex_;
  std::uint64_t lost_ = 0, rejected_ = 0;  // this reader's totals seen so far
};

// What each reader listens to: data, and the samples DDS gave up on.
fdds::StatusMask listenedStatus() {
  fdds::StatusMask m = fdds::StatusMask::data_available();
  m << fdds::StatusMask::sample_lost() << fdds::StatusMask::sample_rejected();
  return m;
}
}  // namespace

template <class T>
struct Reader<T>::Impl : Endpoint {
  std::shared_ptr<Participant::Core> core;
  std::string topic;
  std::unique_ptr<DataListener> listener;  // outlives the DataReader (deleted in release first)
  mutable std::mutex mutex;               // guards reader and scratch
  fdds::DataReader* reader = nullptr;
  T scratch;                              // take() target: `out` is untouched when nothing valid
  std::atomic<std::uint64_t> received{0};
  std::atomic<std::uint64_t> rejected{0};

  void release() override {
    std::lock_guard<std::mutex> lock(mutex);
    // delete_datareader returns once no listener callback runs any more.
    if (reader != nullptr && core->subscriber != nullptr) core->subscriber->delete_datareader(reader);
    reader = nullptr;
  }
};

template <class T>
Reader<T>::Reader(Participant& participant, const std::string& topic, const std::string& profile)
    : Reader(participant, topic, profile, 0) {}

template <class T>
Reader<T>::Reader(Participant& participant, const std::string& topic, const std::string& profile, int keep_last)
    : impl_(new Impl) {
  impl_->core = participant.core_;
  impl_->topic = topic;
  Participant::Core& c = *impl_->core;
  std::lock_guard<std::mutex> lock(c.entities);
  fdds::Topic* t = c.template topic<typename WireType<T>::PubSub>(topic);
  c.requireEndpointProfile(false, profile);
  const std::uint64_t mark = errorMark();
  fdds::DataReaderQos qos;
  if (c.subscriber->get_datareader_qos_from_profile(profile, qos) != eprosima::fastrtps::types::ReturnCode_t::RETCODE_OK)
    throw DdsError(std::string(kPrefix) + "no data_reader profile " + inQuotes(profile) + " in " + inQuotes(c.profiles_file));
  if (keep_last > 0 && qos.history().kind == fdds::KEEP_LAST_HISTORY_QOS)
    qos.history().depth = std::max(qos.history().depth, keep_last);
  const bool newest_only = qos.reliability().kind == fdds::RELIABLE_RELIABILITY_QOS &&
                           qos.history().kind == fdds::KEEP_LAST_HISTORY_QOS && qos.history().depth == 1;
  impl_->listener.reset(new DataListener(impl_->core.get(), topic, newest_only));
  if (keep_last > 0) {
    auto& rl = qos.resource_limits();
    if (rl.max_samples_per_instance > 0) rl.max_samples_per_instance = std::max(rl.max_samples_per_instance, keep_last);
    if (rl.max_samples > 0 && rl.max_instances > 0 && rl.max_samples_per_instance > 0)
      rl.max_samples = std::max(rl.max_samples, rl.max_instances * rl.max_samples_per_instance);
    impl_->reader = c.subscriber->create_datareader(t, qos, impl_->listener.get(), listenedStatus());
  } else {
    impl_->reader =
        c.subscriber->create_datareader_with_profile(t, profile, impl_->listener.get(), listenedStatus());
  }
  if (impl_->reader == nullptr)
    throw DdsError(std::string(kPrefix) + "Fast DDS could not create a reader on " + inQuotes(topic) +
                   " from data_reader profile " + inQuotes(profile) + " of " + inQuotes(c.profiles_file) + errorsSince(mark));
  c.endpoints.insert(impl_.get());
}

template <class T>
Reader<T>::~Reader() {
  Participant::Core& c = *impl_->core;
  std::lock_guard<std::mutex> lock(c.entities);
  c.endpoints.erase(impl_.get());
  impl_->release();
}

template <class T>
bool Reader<T>::take(T& out) {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  if (impl_->reader == nullptr) return false;
  fdds::SampleInfo info;
  for (;;) {
    ReturnCode_t rc = ReturnCode_t::RETCODE_ERROR;
    try {
      rc = impl_->reader->take_next_sample(&impl_->scratch, &info);
    } catch (...) {  // a serializer exception on a malformed sample: counted, never a crash
      impl_->rejected.fetch_add(1, std::memory_order_relaxed);
      impl_->core->samples_malformed.fetch_add(1, std::memory_order_relaxed);
      return false;
    }
    if (rc != ReturnCode_t::RETCODE_OK) return false;
    if (!info.valid_data) continue;  // dispose / unregister notifications
    if (!msg::wire_bounds::within(impl_->scratch)) {
      impl_->rejected.fetch_add(1, std::memory_order_relaxed);
      impl_->core->samples_malformed.fetch_add(1, std::memory_order_relaxed);
      continue;
    }
    using std::swap;
    swap(out, impl_->scratch);  // keeps both buffers' capacity
    impl_->received.fetch_add(1, std::memory_order_relaxed);
    return true;
  }
}

template <class T>
int Reader<T>::matched() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  if (impl_->reader == nullptr) return 0;
  fdds::SubscriptionMatchedStatus status;
  if (impl_->reader->get_subscription_matched_status(status) != ReturnCode_t::RETCODE_OK) return 0;
  return status.current_count;
}

template <class T>
QosInfo Reader<T>::qos() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->reader != nullptr ? qosInfo(impl_->reader->get_qos()) : QosInfo{};
}

template <class T>
std::uint64_t Reader<T>::received() const {
  return impl_->received.load(std::memory_order_relaxed);
}
template <class T>
std::uint64_t Reader<T>::rejected() const {
  return impl_->rejected.load(std::memory_order_relaxed);
}
template <class T>
const std::string& Reader<T>::topic() const {
  return impl_->topic;
}

template class Writer<msg::HandTarget>;
template class Writer<msg::HandProposal>;
template class Writer<msg::HandState>;
template class Writer<msg::ContactForces>;
template class Writer<msg::SceneState>;
template class Writer<msg::SceneDescription>;
template class Writer<msg::ServiceStatus>;
template class Reader<msg::HandTarget>;
template class Reader<msg::HandProposal>;
template class Reader<msg::HandState>;
template class Reader<msg::ContactForces>;
template class Reader<msg::SceneState>;
template class Reader<msg::SceneDescription>;
template class Reader<msg::ServiceStatus>;

}  // namespace godhand::dds
