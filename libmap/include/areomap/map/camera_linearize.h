// Linearizing a camera model to CAHV, as JPL's cmod_cahvor_warp_to_cahv / cmod_cahvore_warp_to_cahv
// do for image resampling (the "minimum field of view" variant):
//   - C stays the model's centre; A is the ray through the input image centre;
//   - the right and down axes come from the model's own image axes (down = A0 x H0), made
//     orthogonal to the new A;
//   - the horizontal (vertical) scale is chosen so that the narrowest of the six landmark rays
//     on the left and right (top and bottom) image borders falls on the output's border pixel
//     centre: hs = ((W_out - 1) / 2) / tan(angle), with the angle measured in the A-right plane.
//   So every output pixel sees inside the input image, and the principal point is the output
//   centre ((W - 1) / 2, (H - 1) / 2). Pixels: first pixel centre at (0, 0).
// The result is in the model's frame. A CAHV whose principal point is the image centre and whose
// pixel axes are orthogonal linearizes to itself.
#pragma once

#include <Eigen/Core>

#include "areomap/map/cahvor.h"
#include "areomap/map/camera_models.h"

namespace areomap {

// Throws areomap::Error if a size is not positive or a landmark ray is 90 degrees or more off
// the new axis (a field of view the CAHV cannot hold).
CahvorModel LinearizeToCahv(const CameraModel& model, const Eigen::Vector2i& input_size,
                            const Eigen::Vector2i& output_size);

}  // namespace areomap
