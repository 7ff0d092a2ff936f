#include "scan/cubist_io.hpp"

#include <algorithm>
#include <cstdio>
#include <filesystem>

#include "core/atomic_file.hpp"
#include "core/errors.hpp"
#include "core/json_util.hpp"
#include "core/png_io.hpp"

namespace handskin {

const char* side_name(ScanSide s) { return s == ScanSide::Back ? "back" : "palm"; }

size_t RangeScan::count_valid() const {
  return static_cast<size_t>(std::count_if(values.begin(), values.end(), [](std::uint16_t v) { return v != 0; }));
}

ScanMeta parse_scan_meta(const std::string& json_text, const std::string& file) {
  const Json j = parse_json_object(json_text, file);
  if (get_string(j, "format", file) != "cubist-range/1")
    throw InputError(file, "key 'format' must be \"cubist-range/1\"");
  ScanMeta m;
  // Grids are bounded so that a small file cannot make the pipeline take gigabytes: a
  // table-only scan has a return in every pixel, and every return becomes a point of the
  // registration. CUBIST is 512 x 512; the cap is 16 times its pixels (docs/formats.md).
  m.scanlines = static_cast<int>(get_int(j, "scanlines", file, 1, kMaxScanSide));
  m.points = static_cast<int>(get_int(j, "points", file, 1, kMaxScanSide));
  if (static_cast<long>(m.scanlines) * m.points > kMaxScanPixels)
    throw InputError(file, "keys 'scanlines' x 'points' = " + std::to_string(static_cast<long>(m.scanlines) * m.points) +
                               " samples, more than the " + std::to_string(kMaxScanPixels) + " a scan may hold");
  // Origins and steps are bounded so that every sample's coordinate stays finite and
  // meaningful in mm (a step of 1e308 would make infinities out of finite numbers).
  auto bounded = [&](const char* key, double lo, double hi) {
    const double v = get_finite(j, key, file);
    if (!(v >= lo && v <= hi))
      throw InputError(file, std::string("key '") + key + "' must be in [" + number_text(lo) + ", " + number_text(hi) +
                                 "] mm (got " + number_text(v) + ")");
    return v;
  };
  m.x_origin_mm = bounded("x_origin_mm", -kMaxScanOriginMm, kMaxScanOriginMm);
  m.x_step_mm = get_positive(j, "x_step_mm", file);
  m.x_step_mm = bounded("x_step_mm", kMinScanStepMm, kMaxScanStepMm);
  m.y_origin_mm = bounded("y_origin_mm", -kMaxScanOriginMm, kMaxScanOriginMm);
  m.y_step_mm = get_positive(j, "y_step_mm", file);
  m.y_step_mm = bounded("y_step_mm", kMinScanStepMm, kMaxScanStepMm);
  m.z_origin_mm = bounded("z_origin_mm", -kMaxScanOriginMm, kMaxScanOriginMm);
  m.z_step_mm = get_positive(j, "z_step_mm", file);
  m.z_step_mm = bounded("z_step_mm", kMinScanStepMm, kMaxScanStepMm);
  const std::string side = get_string(j, "side", file);
  if (side == "back") m.side = ScanSide::Back;
  else if (side == "palm") m.side = ScanSide::Palm;
  else throw InputError(file, "key 'side' must be \"back\" or \"palm\" (got \"" + side + "\")");
  if (j.contains("device")) m.device = get_string(j, "device", file);
  if (j.contains("notes")) m.notes = get_string(j, "notes", file);
  return m;
}

std::string scan_meta_to_json_text(const ScanMeta& m) {
  Json j;
  j["format"] = "cubist-range/1";
  j["scanlines"] = m.scanlines;
  j["points"] = m.points;
  j["x_origin_mm"] = m.x_origin_mm;
  j["x_step_mm"] = m.x_step_mm;
  j["y_origin_mm"] = m.y_origin_mm;
  j["y_step_mm"] = m.y_step_mm;
  j["z_origin_mm"] = m.z_origin_mm;
  j["z_step_mm"] = m.z_step_mm;
  j["side"] = side_name(m.side);
  if (!m.device.empty()) j["device"] = m.device;
  if (!m.notes.empty()) j["notes"] = m.notes;
  return j.dump(2) + "\n";
}

RangeScan decode_scan(const std::string& png_bytes, const std::string& png_name, const std::string& json_text,
                      const std::string& json_name) {
  RangeScan scan;
  scan.meta = parse_scan_meta(json_text, json_name);
  Gray16Image img = decode_gray16_png(png_bytes, png_name, std::max(scan.meta.scanlines, scan.meta.points));
  if (img.height != scan.meta.scanlines)
    throw InputError(json_name, "key 'scanlines' is " + std::to_string(scan.meta.scanlines) + " but " + png_name +
                                    " has " + std::to_string(img.height) + " rows");
  if (img.width != scan.meta.points)
    throw InputError(json_name, "key 'points' is " + std::to_string(scan.meta.points) + " but " + png_name +
                                    " has " + std::to_string(img.width) + " columns");
  scan.values = std::move(img.pixels);
  if (scan.count_valid() == 0) throw InputError(png_name, "empty scan: every pixel is 0 (no return)");
  return scan;
}

std::string scan_stem(const std::string& given) {
  for (const std::string suffix : {".json", ".png"}) {
    if (given.size() <= suffix.size() || given.compare(given.size() - suffix.size(), suffix.size(), suffix) != 0) continue;
    std::error_code ec;
    if (std::filesystem::exists(given + ".json", ec)) return given;
    return given.substr(0, given.size() - suffix.size());
  }
  return given;
}

RangeScan load_scan(const std::string& stem) {
  const std::string png = stem + ".png", json = stem + ".json";
  const std::string json_text = read_file(json);  // the sidecar first: its errors are the clearer ones
  return decode_scan(read_file(png), png, json_text, json);
}

void save_scan(const std::string& stem, const RangeScan& scan, int png_level) {
  HS_CHECK(scan.values.size() == static_cast<size_t>(scan.meta.scanlines) * scan.meta.points,
           "scan size disagrees with its metadata");
  Gray16Image img{scan.meta.points, scan.meta.scanlines, scan.values};
  write_file_atomic(stem + ".png", encode_gray16_png(img, png_level));
  write_file_atomic(stem + ".json", scan_meta_to_json_text(scan.meta));
}

RangeScan load_scan_side(const std::string& stem, ScanSide side, const std::string& option) {
  RangeScan s = load_scan(stem);
  if (s.meta.side != side)
    throw InputError(stem + ".json", std::string("key 'side' is \"") + side_name(s.meta.side) +
                                         "\" but this scan was given as " + option);
  return s;
}

}  // namespace handskin
