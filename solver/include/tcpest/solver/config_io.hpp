// Loading the camera calibration (ROS camera_info YAML, also as OpenCV's
// FileStorage writes it) and the instrument geometry (the `instrument`,
// `channel_nominal` and `play_penalty` sections of a tcpest config file).
// Init-time only. Every error names the file, the line and the field.
#pragma once

#include "tcpest/common/diagnostic.hpp"
#include "tcpest/common/result.hpp"
#include "tcpest/common/yaml_lite.hpp"
#include "tcpest/solver/camera.hpp"
#include "tcpest/solver/instrument.hpp"

namespace tcpest {
namespace solver {

// Reads and validates a camera calibration (docs/model.md). Required:
// image_width, image_height, camera_matrix.data (9 values, [fx 0 cx; 0 fy
// cy; 0 0 1]) and distortion_coefficients.data (4 or 5 values, or more when
// the extra ones are zero), and either distortion_model (plumb_bob: ROS) or
// OpenCV matrices (rows, cols, dt d or f, rows x cols values in data; no
// distortion_model). OpenCV's other spellings of the two matrices
// (cameraMatrix / distCoeffs, Camera_Matrix / Distortion_Coefficients) are
// read too.
Result<CameraIntrinsics, Diagnostic> read_camera_info(const yaml::Document& doc) noexcept;
// The top-level keys read_camera_info reads: parse a calibration with them
// so that the rest of the file (an OpenCV calibration's image points, of any
// size) is skipped, not stored.
yaml::KeySet camera_info_keys() noexcept;
// `scratch` is the (large) parse buffer; keep it in static storage.
Result<CameraIntrinsics, Diagnostic> load_camera_info(const char* path, yaml::Document& scratch) noexcept;

// Reads the geometry sections; every key is optional (defaults of
// InstrumentGeometry), unknown keys in these sections are refused, and the
// result is validated.
Result<InstrumentGeometry, Diagnostic> read_instrument_config(const yaml::Document& doc) noexcept;
Result<InstrumentGeometry, Diagnostic> load_instrument_config(const char* path, yaml::Document& scratch) noexcept;

}  // namespace solver
}  // namespace tcpest
