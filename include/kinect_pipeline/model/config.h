/**
 * @file config.h
 * @brief The one configuration struct of the pipeline. Field names are the ROS parameter names.
 */
#pragma once

#include <string>
#include <vector>

namespace kinect_pipeline
{

/** How the floor and ceiling depths are predicted. */
enum class Geometry
{
  kExact,   ///< exact pinhole ray / plane intersection, with roll (default)
  kThesis,  ///< the thesis: linear row angle (eq 4.10), intercepts cos(pitch)*h (eq 4.14), no roll
};

/** How kept pixels become laser beams. */
enum class Projection
{
  kHorizontal,  ///< each pixel in the gravity-aligned frame under the sensor, range = hypot(X, Y) (default)
  kColumn,      ///< the thesis: each pixel by its column angle, range = z / cos(theta_x) (eq 4.21/4.22)
};

/** Structuring element of the morphological opening (OpenCV's MORPH_RECT, MORPH_CROSS, MORPH_ELLIPSE). */
enum class KernelShape
{
  kRect,
  kCross,
  kEllipse,
};

/** One control point of the depth-dependent threshold curve t(d). */
struct CurvePoint
{
  double depth;      ///< depth along the optical axis [m]
  double threshold;  ///< allowed distance from the predicted floor at that depth [m]
};

/**
 * @brief The default threshold curve, made for a Kinect v2.
 *
 * Its depth noise is about sigma(z) = 1.5 mm + 1.9 mm * (z - 0.4 m)^2; the curve is about
 * 2 cm + 4.5 sigma sampled at a few depths (see README, "Threshold curve").
 */
std::vector<CurvePoint> defaultThresholdCurve();

/** Parses "d0:t0, d1:t1, ..." (metres) into control points. @throw std::invalid_argument on bad text. */
std::vector<CurvePoint> parseThresholdCurve(const std::string& text);
/** Formats control points as "d0:t0, d1:t1, ..." (the inverse of parseThresholdCurve()). */
std::string formatThresholdCurve(const std::vector<CurvePoint>& curve);

/** Geometry from its parameter name ("exact" | "thesis"). @throw std::invalid_argument otherwise. */
Geometry geometryFromString(const std::string& s);
/** Projection from its parameter name ("horizontal" | "column"). @throw std::invalid_argument otherwise. */
Projection projectionFromString(const std::string& s);
/** Kernel shape from its parameter name ("rect" | "cross" | "ellipse"). @throw std::invalid_argument otherwise. */
KernelShape kernelShapeFromString(const std::string& s);
std::string toString(Geometry g);
std::string toString(Projection p);
std::string toString(KernelShape k);

/**
 * Everything the pipeline needs besides the camera model and the per-frame base pose.
 *
 * Frames: the sensor's pose is given relative to a gravity-aligned frame on the floor right under it
 * (x forward, y left, z up; REP 103). Pitch is positive when the sensor looks down, roll positive when the
 * right side is down. The base's pitch and roll of each frame are added to sensor_pitch / sensor_roll.
 */
struct Config
{
  double sensor_height = 1.1;   ///< height of the optical centre above the floor [m], > 0
  double sensor_pitch = 0.0;    ///< static tilt of the sensor on the base [rad], + looks down
  double sensor_roll = 0.0;     ///< static roll of the sensor on the base [rad], + right side down, +-pi upside down
  double ceiling_height = 2.0;  ///< height of the ceiling plane above the floor [m], > sensor_height
  double max_depth = 12.0;      ///< depth of 8-bit value 255 [m] (value v <-> v / 255 * max_depth)

  Geometry geometry = Geometry::kExact;
  Projection projection = Projection::kHorizontal;

  int open_kernel_size = 3;                     ///< opening kernel size [px]: 0 or 1 = off, else odd >= 3
  KernelShape open_kernel_shape = KernelShape::kRect;
  /// wrong matches (stereo cameras): a pixel nearer, by more than this fraction of its depth, than each of the four
  /// pixels two steps away is taken as no measurement before the opening (stages/speckle.h); 0 = off
  double speckle_jump = 0.0;

  std::vector<CurvePoint> threshold_curve = defaultThresholdCurve();  ///< t(d) control points [m]

  double range_min = 0.1;   ///< shorter horizontal ranges are reported as -Inf (REP 117) [m]
  double range_max = 10.0;  ///< longer ranges are reported as +Inf (no return) [m]
  int scan_beams = 0;       ///< number of beams; 0 = the image width
  double scan_fov = 0.0;    ///< angular width of the scan [rad], centred on forward; 0 = the camera's
  /// Range of a beam: 0 = its nearest kept pixel (the thesis); > 0 = the mean of the measured (unopened) ranges
  /// of its kept pixels no farther than surface_band * t(r) beyond the nearest one, r being that nearest range:
  /// the nearest surface's range, not the noise's nearest tail (a second pass over the kept pixels). [-], 0..10
  double surface_band = 0.0;

  /// Negative obstacles (pixels more than t(d) below the floor: a hole, a stair down, a dock edge).
  bool cliff_scan = true;      ///< fill FrameResult::cliff: nearest below-floor pixel per beam
  bool cliff_in_scan = false;  ///< also put below-floor beams into the main scan as obstacles
  int cliff_min_pixels = 3;    ///< below-floor pixels a beam needs before it reports a cliff [px], >= 1
  /// Smallest drop a cliff beam reports [m]: a below-floor pixel counts only at least this far below the floor and
  /// within the depth where such a drop is told from t(d); a cliff no nearer than its beam's obstacle is dropped.
  /// 0 = every below-floor pixel counts (docs/negative_obstacles.md, "Evidence").
  double cliff_min_drop = 0.05;

  int confidence_window = 5;         ///< N: ranges in each beam's rolling mean (incl. the current one)
  double confidence_distance = 0.3;  ///< d_threshold of eq 4.23 [m]
  double min_intensity = 0.2;        ///< intensity at or below which a filtered beam becomes NaN
  bool intensity_filter = false;     ///< NaN the finite beams with intensity <= min_intensity

  /// Floor refinement (stages/floor_fit.h): the pose corrected from the frame's own floor before the planes are
  /// predicted.
  bool refine_floor = true;              ///< fit the floor to the frame; false: the pose exactly as given
  double floor_max_height_error = 0.08;  ///< largest correction of the sensor height [m] (and the band searched)
  double floor_max_pitch_error = 0.035;  ///< largest correction of the pitch [rad] (2 deg)
  double floor_max_roll_error = 0.035;   ///< largest correction of the roll [rad] (2 deg)
  int floor_min_pixels = 4000;           ///< fewest image pixels on the fitted floor to accept it [px]
  double floor_learn_time = 2.0;         ///< time constant of the learned correction [s]; 0 = learn nothing
  /// largest height [m] by which the learned floor profile departs from the plane (stages/floor_profile.h); 0 = none
  double floor_profile_max = 0.025;

  int num_threads = 0;  ///< OpenMP threads for one frame; 0 = OpenMP's default

  /**
   * @brief Every invalid field and combination, one message each ("Config.<field> = <value>: expected ...");
   *        empty when the config is valid. A combination is judged only when its fields are valid on their own.
   */
  std::vector<std::string> problems() const;

  /**
   * @brief Checks every field and their combinations.
   * @throw std::invalid_argument naming the field(s), the value(s) and what was expected: every problem(), joined
   *        by "; ".
   */
  void validate() const;
};

/**
 * @brief What is wrong with a roll under a geometry: beyond +-pi/2 the thesis's planes (an upright camera's, which
 *        leave the roll out) do not hold; any roll holds for the exact geometry.
 * @param what the roll's name in the message ("Config.sensor_roll", "pose: roll")
 * @return "" where it holds, else "<what> = <roll> rad with geometry 'thesis': expected ..."
 */
std::string rollProblem(double roll, Geometry geometry, const char* what);

}  // namespace kinect_pipeline
