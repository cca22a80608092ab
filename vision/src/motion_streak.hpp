// The motion-blur streak read from the model's boundary arcs and the
// blue stripes' silhouette at a pose (docs/decisions/0014-motion-streak-reading.md),
// for the image fit and
// FeatureExtractor::read_motion_streak.
#pragma once

#include "tcpest/vision/features.hpp"

namespace tcpest {
namespace vision {
namespace detail {

// The motion-blur streak (px, image; its sign is arbitrary) read on the
// stripe boundaries' visible arcs at the frames f: at kStreakArcPoints of
// each arc the change's width w along the arc's image normal n, then
// M = b b^T from w^2 - kStreakSharpWidthPx^2 = n^T M n by linear least
// squares, once more without the widths far off the first fit (a vessel or
// a highlight beside the arc); the streak is M's main axis. False with
// fewer than kMinStreakWidths widths or a singular fit.
bool read_streak(const ImageView& image, const ExtractorConfig& config, const solver::CameraModel& camera,
                 const solver::InstrumentModel& model, const solver::PoseFrames& f, solver::Vec2& streak_px) noexcept;

// refine_streak_arc_retry: true when a fine iteration that read too few
// boundaries is to be read again with the arcs widened under the streak;
// the streak read at the frames f when none is held yet (a smear along the
// tube can hide every arc, so the arcs never read as smeared).
bool streak_for_arc_retry(const ImageView& image, const ExtractorConfig& config, const solver::CameraModel& camera,
                          const solver::InstrumentModel& model, const solver::PoseFrames& f,
                          solver::Vec2& streak_px) noexcept;

}  // namespace detail
}  // namespace vision
}  // namespace tcpest
