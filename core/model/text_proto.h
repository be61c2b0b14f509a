// The one reader of godhand's protobuf text files (hand models, scenes, labs, sweep grids): parses
// `text` into `msg`, recording each field's location in `tree` for "FILE:LINE: field: reason"
// messages, and on a syntax error gives the parser's first error as "LINE:COLUMN: message".
#pragma once

#include <google/protobuf/message.h>
#include <google/protobuf/text_format.h>

#include <string>

namespace godhand {

/// True on success; false with `*error` = "LINE:COLUMN: message" (1-based), or `fallback` when the
/// parser recorded no error.
bool parseTextProto(const std::string& text, google::protobuf::Message* msg,
                    google::protobuf::TextFormat::ParseInfoTree* tree, std::string* error,
                    const std::string& fallback);

}  // namespace godhand
