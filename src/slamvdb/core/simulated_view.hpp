#pragma once
// The SIMULATED view geometry image a synthetic sequence carries beside each camera image
// (pylon_camera_node_sim_view/, written by synth, read by the simulated encoder): per pixel, one
// 16-bit value in each of three channels:
//   0: range along the pixel's ray in centimetres (0: sky, nothing hit; saturates at 655 m)
//   1: cosine of the incidence angle between the ray and the surface normal, x 65535
//   2: a world-fixed appearance value of the surface point (smooth noise over the world, mean 0,
//      sd about 1.3), as 32768 + 8192 x value: the same place has the same value in every view,
//      so an encoder error keyed to it persists across views.
// Real datasets have no such image; it exists so that the simulated encoder can fail as a network
// does where surfaces are far, seen at grazing angles, or look like another class.
#include <cstdint>

namespace slamvdb {

inline constexpr double kViewRangeUnit = 0.01;  // metres per unit of channel 0
inline constexpr double kViewAppearanceScale = 8192.0;

inline double view_range(uint16_t v) { return v * kViewRangeUnit; }
inline double view_incidence_cos(uint16_t v) { return v / 65535.0; }
inline double view_appearance(uint16_t v) { return (static_cast<double>(v) - 32768.0) / kViewAppearanceScale; }

}  // namespace slamvdb
