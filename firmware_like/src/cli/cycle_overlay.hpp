// The overlay of one loop cycle (tcpest demo, tcpest run --record): the frame
// with the extraction's borders and corners, the model re-projected at the
// estimate, the estimated TCP, and the true TCP as a green cross when the
// source knows it. No allocation.
#pragma once

#include "cli/setup.hpp"
#include "tcpest/common/image.hpp"
#include "tcpest/hal/camera/sim_camera.hpp"
#include "tcpest/loop/executive.hpp"
#include "tcpest/vision/extraction.hpp"

namespace tcpest {
namespace cli {

// Copies `frame` into `out` (the same size) and draws on it. `extraction`
// (nullptr: none drawn) is the cycle's; `truth` (nullptr or not valid: no
// cross) the frame's.
void draw_cycle_overlay(const MutableImageView& out, const ImageView& frame, const vision::Extraction* extraction,
                        const ModelSetup& models, const loop::CycleRecord& r, const hal::FrameTruth* truth) noexcept;

}  // namespace cli
}  // namespace tcpest
