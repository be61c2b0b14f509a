// Project Aria MPS hand tracking results (hand_tracking_results_v2.csv): per row the tracking
// timestamp (µs), then per hand (left, right) a tracking confidence (−1 = not tracked) and 21
// landmarks in the device frame (metres), columns tx/ty/tz_{left,right}_landmark_{0..20}_device
// (further columns, e.g. wrist poses and palm normals, are ignored). Columns are found by name.
// Aria's landmark order: 0..4 fingertips (thumb..little), 5 wrist, 6 thumb intermediate (MCP),
// 7 thumb distal (IP), 8..10 index proximal (MCP) / intermediate (PIP) / distal (DIP), 11..13
// middle, 14..16 ring, 17..19 little, 20 palm centre. Aria has no thumb CMC: it is placed a
// third of the way from the wrist to the thumb MCP (an approximation; it only orients thumb.1).
// The device frame is taken as the tracker frame T: give its pose in the world with X_WT.
#pragma once

#include <string>

#include "skeleton/jsonl.h"

namespace godhand::skeleton {

/// True when the first line is an Aria MPS hand tracking header.
bool isAriaHeader(const std::string& first_line);

/// Parses the CSV text. Throws JsonlError ("NAME: reason") when a needed column is missing;
/// bad rows / hands are counted by reason (format "aria").
JsonlRecording readAriaCsv(const std::string& text, const std::string& name, const Pose& X_WT = Pose());

}  // namespace godhand::skeleton
