// The rendered scenes the core tests share (the ray caster's, tools/synthetic.h): a lab, boxes on a bare floor, a hole
// in the floor, a stair down across the whole view.
#pragma once

#include "kinect_pipeline/tools/synthetic.h"

namespace kp_test
{
/** Benches, a tall cabinet, a 5 cm box, a shelf board in the air, a far wall, a hole and a 2.7 m ceiling. */
inline kinect_pipeline::Scene labScene()
{
  kinect_pipeline::Scene s;
  s.ceiling = 2.7;
  s.boxes = {{1.5, 2.0, -0.4, 0.3, 0.0, 0.6}, {2.5, 2.9, 0.5, 1.0, 0.0, 1.8}, {3.0, 3.3, -1.2, -0.9, 0.0, 0.05},
             {1.2, 1.6, 0.8, 1.2, 1.5, 1.7}, {4.5, 4.8, -3.0, 3.0, 0.0, 2.7}};
  s.holes = {{2.0, 2.4, -1.2, -0.6, 0, 0}};
  return s;
}

/** A bare floor with boxes of 40, 25, 120 and 5 cm (no walls, no ceiling). */
inline kinect_pipeline::Scene boxesScene()
{
  kinect_pipeline::Scene s;
  s.boxes = {{1.5, 1.9, -0.5, 0.0, 0.0, 0.40}, {2.2, 2.6, 0.3, 0.8, 0.0, 0.25}, {3.0, 3.3, -1.2, -0.8, 0.0, 1.20},
             {2.0, 2.2, -0.1, 0.1, 0.0, 0.05}};
  return s;
}

/** A hole in the floor ahead and to the left, 50 cm deep. */
inline kinect_pipeline::Scene holeScene()
{
  kinect_pipeline::Scene s;
  s.holes = {{2.0, 2.6, -0.2, 0.6, 0, 0}};
  s.hole_depth = 0.5;
  return s;
}

/** The floor ends 3 m ahead across the whole view; the next step is 17 cm lower. */
inline kinect_pipeline::Scene stairScene()
{
  kinect_pipeline::Scene s;
  s.holes = {{3.0, 30.0, -30.0, 30.0, 0, 0}};
  s.hole_depth = 0.17;
  return s;
}
}  // namespace kp_test
