/**
 * @file config_fields.h
 * @brief The one table of Config fields: name, kind, valid range, unit and meaning of each.
 *
 * Everything that lists the fields reads this table: Config::problems() (the range checks), the Python binding
 * (attributes, keyword arguments, docstrings, to_dict), the ROS node's parameter mapping and the fuzzer.
 * cfg/KinectPipeline.cfg declares the same fields for dynamic_reconfigure (its generator runs before the core is
 * built); test/python/test_ros_params.py checks it against this table: names, types, ranges and defaults.
 * Adding a field to Config means adding one row here (src/core/model/config_table.cpp) and one line to the .cfg.
 */
#pragma once

#include <string>
#include <vector>

#include "kinect_pipeline/model/config.h"

namespace kinect_pipeline
{

/** What a field holds, and so how it is read and written. */
enum class FieldKind
{
  kReal,     ///< a double, valid in [lo, hi]
  kInteger,  ///< an int, valid in [lo, hi]
  kFlag,     ///< a bool
  kChoice,   ///< one of a few names (geometry, projection, open_kernel_shape)
  kCurve,    ///< the threshold curve: "d0:t0, d1:t1, ..." as text
};

/** One row of the table. */
struct ConfigField
{
  const char* name;  ///< the C++ member, the Python attribute and the ROS parameter
  FieldKind kind;
  double lo;         ///< smallest valid value (kReal, kInteger)
  double hi;         ///< largest valid value (kReal, kInteger)
  const char* unit;  ///< "m", "rad", "px", "s", "frames" or "-"
  const char* doc;   ///< what it means, one line

  double Config::*real = nullptr;     ///< kReal
  int Config::*integer = nullptr;     ///< kInteger
  bool Config::*flag = nullptr;       ///< kFlag
  std::vector<std::string> choices;   ///< kChoice: the names it accepts
  std::string (*choice_of)(const Config&) = nullptr;          ///< kChoice: the value's name
  void (*set_choice)(Config&, const std::string&) = nullptr;  ///< kChoice: the value from its name (throws on others)

  /** The value as a number (kReal, kInteger, kFlag). @throw std::logic_error for kChoice / kCurve. */
  double number(const Config& c) const;
  /**
   * Sets a number (kReal, kInteger: a whole number, kFlag: 0 or 1). @throw std::invalid_argument, with the range of
   * rangeProblem for an integer that its type cannot hold
   */
  void setNumber(Config& c, double v) const;
  /** The value as its parameter text: a choice's name, the curve as "d:t, ...", a number in full precision. */
  std::string text(const Config& c) const;
  /** Sets a choice or the curve from its text (numbers too). @throw std::invalid_argument naming the value. */
  void setText(Config& c, const std::string& v) const;
  /** "Config.<name> = <v>: expected ..." when a kReal / kInteger value lies outside [lo, hi], else "". */
  std::string rangeProblem(const Config& c) const;
  /** The same for a value @p v given for this field (one too large for its type, say). */
  std::string rangeProblem(double v) const;
};

/** Every field of Config, in the order of model/config.h. */
const std::vector<ConfigField>& configFields();

/** The row named @p name. @throw std::invalid_argument naming it and listing the fields. */
const ConfigField& configField(const std::string& name);

}  // namespace kinect_pipeline
