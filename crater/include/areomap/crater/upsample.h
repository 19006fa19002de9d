// The crater detector's 2x upsampled level (crater_detector.h: small craters are searched on a
// 2x upsampled copy of each tile).
//
// Frame: GDAL's pixel convention on both images; output pixel (x, y) has its centre at input
// ((x + 0.5) / 2, (y + 0.5) / 2), so coordinates scale exactly by 2.
#pragma once

#include <opencv2/core.hpp>

namespace areomap {

// `image` (CV_32F, single band) upsampled 2x by bilinear interpolation into `out` (reallocated
// unless it already is 2 rows x 2 cols CV_32F; it must not overlap `image`): bit for bit the
// values of cv::resize(image, *out, {2 cols, 2 rows}, 0, 0, cv::INTER_LINEAR), the input's border
// replicated, a non-finite input pixel spreading to the output pixels whose two-by-two taps
// include it (with weight 0 at the left column). Output rows are written with streaming stores:
// a tile's copy is not read back before it leaves the cache (docs/notes/benchmarks-history.md,
// crater speed round 13). Rows in parallel (TBB). Throws areomap::Error for another image type;
// an image under 2 x 2 px goes to cv::resize.
void UpsampleTwice(const cv::Mat& image, cv::Mat* out);

}  // namespace areomap
