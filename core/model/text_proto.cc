#include "model/text_proto.h"

#include <google/protobuf/io/tokenizer.h>

namespace godhand {

namespace {
/// Collects the first syntax error of the text parser with its position.
class FirstError : public google::protobuf::io::ErrorCollector {
 public:
  void AddError(int line, google::protobuf::io::ColumnNumber column, const std::string& message) override {
    if (!has) {
      has = true;
      text = std::to_string(line + 1) + ":" + std::to_string(column + 1) + ": " + message;
    }
  }
  void AddWarning(int, google::protobuf::io::ColumnNumber, const std::string&) override {}
  bool has = false;
  std::string text;
};
}  // namespace

bool parseTextProto(const std::string& text, google::protobuf::Message* msg,
                    google::protobuf::TextFormat::ParseInfoTree* tree, std::string* error,
                    const std::string& fallback) {
  FirstError errors;
  google::protobuf::TextFormat::Parser parser;
  parser.RecordErrorsTo(&errors);
  parser.WriteLocationsTo(tree);
  if (parser.ParseFromString(text, msg)) return true;
  *error = errors.has ? errors.text : fallback;
  return false;
}

}  // namespace godhand
