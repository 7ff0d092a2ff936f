#pragma once
/// `cubist-range/1`: one side of a CUBIST range scan, a 16-bit PNG plus a JSON sidecar
/// sharing one stem (formats/cubist-range.md).
#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

namespace handskin {

enum class ScanSide { Back, Palm };
const char* side_name(ScanSide s);

/// The largest grid a scan may have: 4096 on a side and 2048 x 2048 samples in all (16 times
/// CUBIST's 512 x 512). Larger sidecars are refused before the image is decoded.
constexpr int kMaxScanSide = 4096;
constexpr long kMaxScanPixels = 2048L * 2048L;
/// Origins within ±1 km and steps in [1 nm, 1 m]: every coordinate finite, in mm.
constexpr double kMaxScanOriginMm = 1e6, kMinScanStepMm = 1e-6, kMaxScanStepMm = 1e3;

struct ScanMeta {
  int scanlines = 512;                  ///< rows (X = const lines)
  int points = 512;                     ///< columns along a scanline
  double x_origin_mm = 0, x_step_mm = 250.0 / 512;
  double y_origin_mm = 0, y_step_mm = 200.0 / 512;
  double z_origin_mm = 0, z_step_mm = 0.2;
  ScanSide side = ScanSide::Back;
  std::string device;                   ///< optional free text
  std::string notes;                    ///< optional free text
};

/// A range image: `values[i * points + j]` is scanline i, point j; 0 = no return.
struct RangeScan {
  ScanMeta meta;
  std::vector<std::uint16_t> values;

  std::uint16_t at(int i, int j) const { return values[static_cast<size_t>(i) * meta.points + j]; }
  bool valid(int i, int j) const { return at(i, j) != 0; }
  /// Scanner-frame position of sample (i, j); meaningful only where valid(i, j).
  Eigen::Vector3d position(int i, int j) const {
    return {meta.x_origin_mm + i * meta.x_step_mm, meta.y_origin_mm + j * meta.y_step_mm,
            meta.z_origin_mm + at(i, j) * meta.z_step_mm};
  }
  size_t count_valid() const;
};

/// Parse the sidecar JSON (`file` names it in errors).
ScanMeta parse_scan_meta(const std::string& json_text, const std::string& file);
std::string scan_meta_to_json_text(const ScanMeta& meta);

/// Decode a scan from its two files' contents. `png_name`/`json_name` are used in errors.
/// Checks sizes against the metadata and refuses an empty scan (every pixel 0).
RangeScan decode_scan(const std::string& png_bytes, const std::string& png_name, const std::string& json_text,
                      const std::string& json_name);

/// The stem of a scan given by its stem or by either of its two files: "back.json" and
/// "back.png" mean "back" (unless "back.json.json" exists, i.e. the stem really ends so).
std::string scan_stem(const std::string& given);
/// Read `<stem>.png` + `<stem>.json`.
RangeScan load_scan(const std::string& stem);
/// load_scan, and the sidecar's `side` must be `side`; `option` (e.g. "--back") names where
/// the scan was given in the error.
RangeScan load_scan_side(const std::string& stem, ScanSide side, const std::string& option);
/// Write `<stem>.png` + `<stem>.json`, each atomically.
void save_scan(const std::string& stem, const RangeScan& scan, int png_level = 9);

}  // namespace handskin
