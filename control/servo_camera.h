#pragma once
// The calibrated camera of the visual compliance law (servo_law.h, ServoCamera) from the files `visco track` and
// `visco sim` read: the calibration (intrinsics), the extrinsics (wMc) and the object models (the robot's height:
// vision tracks the top of the robot's vertical edges). visco::control links no vision, ViSP or OpenCV: this reads the
// subset of those formats the law needs (ViSP XML and OpenCV JSON calibrations; YAML is refused with a hint), at
// start-up. tests/control/servo_camera_test.cc checks it against vision's loaders.

#include <string>

#include "control/servo_law.h"

namespace visco::control {

/// Reads the three files. Intrinsics: of ViSP XML's first camera, the model with distortion when both are given (the
/// ideal pixels vision measures in, vision/camera.h); of an OpenCV JSON calibration, camera_matrix. Extrinsics: the
/// JSON of common/extrinsics.h ("t" and "R" or "rpy_deg"). Objects: "robot"."height".
/// @throws InputError naming the file and the entry that is missing or wrong.
ServoCamera LoadServoCamera(const std::string& calibration_path, const std::string& extrinsics_path,
                            const std::string& objects_path);

}  // namespace visco::control
