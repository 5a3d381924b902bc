#include "kinect_pipeline/ros/parameters.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <set>
#include <sstream>

#include <boost/any.hpp>
#include <xmlrpcpp/XmlRpcValue.h>

#include "kinect_pipeline/model/config_table.h"
#include "kinect_pipeline/model/sensor_model.h"
#include "kinect_pipeline/model/threshold_curve.h"

namespace kinect_pipeline
{
namespace
{
using Description = KinectPipelineConfig::AbstractParamDescription;

const Description* findDescription(const std::string& name)
{
  for (const auto& d : KinectPipelineConfig::__getParamDescriptions__())
    if (d->name == name)
      return d.get();
  return nullptr;
}

/** A problem message as the user sees it: "~field = value: ...". */
std::string named(const std::string& message)
{
  std::string m = asParameterNames(message);
  if (m.empty())
    return m;
  const std::string first = m.substr(0, m.find_first_of(" :"));
  if (m.front() != '~' && findDescription(first))
    m = "~" + m;
  return m;
}

/** The core field @p f from the dynamic_reconfigure config of the same name. @throw std::invalid_argument. */
void copyField(const ConfigField& f, const KinectPipelineConfig& c, Config& k)
{
  const Description* d = findDescription(f.name);
  if (!d)
    throw std::invalid_argument(std::string("Config.") + f.name + " is not in cfg/KinectPipeline.cfg (a build error)");
  boost::any v;
  d->getValue(c, v);
  switch (f.kind)
  {
    case FieldKind::kReal:
      f.setNumber(k, boost::any_cast<double>(v));
      break;
    case FieldKind::kInteger:
      f.setNumber(k, boost::any_cast<int>(v));
      break;
    case FieldKind::kFlag:
      f.setNumber(k, boost::any_cast<bool>(v) ? 1.0 : 0.0);
      break;
    case FieldKind::kChoice:
    case FieldKind::kCurve:
      f.setText(k, boost::any_cast<std::string>(v));
      break;
  }
}

/** Every problem of a config, and the settings it gives where they are fine. */
std::vector<std::string> settingsProblems(const KinectPipelineConfig& c, NodeSettings& s)
{
  std::vector<std::string> problems;
  auto attempt = [&problems](auto&& parse) {
    try
    {
      parse();
    }
    catch (const std::invalid_argument& e)
    {
      problems.push_back(named(e.what()));
    }
  };
  Config& k = s.core;
  for (const ConfigField& f : configFields())
    attempt([&] { copyField(f, c, k); });
  for (const std::string& p : k.problems())
    problems.push_back(named(p));

  s.pose_source = c.pose_source;
  if (s.pose_source != "tf" && s.pose_source != "imu" && s.pose_source != "pitch_topic" && s.pose_source != "static")
    problems.push_back("~pose_source = '" + s.pose_source + "': expected tf, imu, pitch_topic or static");
  s.pose_fallback = c.pose_fallback;
  if (s.pose_fallback != "static" && s.pose_fallback != "last" && s.pose_fallback != "drop")
    problems.push_back("~pose_fallback = '" + s.pose_fallback + "': expected static, last or drop");
  s.rectify = c.rectify;
  if (s.rectify != "auto" && s.rectify != "always" && s.rectify != "never")
    problems.push_back("~rectify = '" + s.rectify + "': expected auto, always or never");
  s.base_frame = c.base_frame;
  s.scan_frame = c.scan_frame;
  if (s.pose_source == "tf" && s.base_frame.empty())
    problems.push_back("~base_frame is empty but ~pose_source = 'tf' needs a gravity-aligned base frame");
  if (s.scan_frame.empty())
    problems.push_back("~scan_frame is empty: the LaserScan needs a frame");
  else if (s.scan_frame == s.base_frame)
    problems.push_back("~scan_frame = ~base_frame = '" + s.base_frame +
                       "': the node broadcasts base_frame -> scan_frame, so they must differ");
  s.base_frame_height = c.base_frame_height;
  s.tf_timeout = c.tf_timeout;
  s.pose_hold_time = c.pose_hold_time;
  s.pose_max_age = c.pose_max_age;
  attempt([&] { s.camera_info = cameraInfoFromParameters(c.intrinsics, c.camera_info_url, s.camera_info_from); });
  return problems;
}

std::string join(const std::vector<std::string>& parts, const std::string& sep)
{
  std::string out;
  for (std::size_t i = 0; i < parts.size(); ++i)
    out += (i ? sep : "") + parts[i];
  return out;
}

/** "2000", "'4' (a string)", "true", "a list": what a parameter value is, for messages. */
std::string describe(XmlRpc::XmlRpcValue& v)
{
  std::ostringstream s;
  switch (v.getType())
  {
    case XmlRpc::XmlRpcValue::TypeBoolean:
      s << (bool(v) ? "true" : "false") << " (a bool)";
      break;
    case XmlRpc::XmlRpcValue::TypeInt:
      s << int(v);
      break;
    case XmlRpc::XmlRpcValue::TypeDouble:
      s << double(v);
      break;
    case XmlRpc::XmlRpcValue::TypeString:
      s << "'" << std::string(v) << "' (a string)";
      break;
    case XmlRpc::XmlRpcValue::TypeArray:
      s << "a list";
      break;
    case XmlRpc::XmlRpcValue::TypeStruct:
      s << "a dictionary";
      break;
    default:
      s << "a value of XML-RPC type " << int(v.getType());
  }
  return s.str();
}

/** The unit of a .cfg description ("... [m]" -> "m"; "-" -> ""). */
std::string unitOf(const std::string& description)
{
  const auto a = description.rfind('['), b = description.rfind(']');
  if (a == std::string::npos || b == std::string::npos || b < a)
    return "";
  const std::string u = description.substr(a + 1, b - a - 1);
  return u == "-" ? "" : " " + u;
}

template <typename T>
T fieldOf(const Description& d, const KinectPipelineConfig& c)
{
  boost::any v;
  d.getValue(c, v);
  return boost::any_cast<T>(v);
}

/** @return what is wrong with @p v as the parameter @p d ("" if nothing). */
std::string typeOrRangeProblem(const Description& d, XmlRpc::XmlRpcValue& v)
{
  const auto type = v.getType();
  std::ostringstream s;
  s << "~" << d.name << " = " << describe(v) << ": expected ";
  if (d.type == "double" || d.type == "int")
  {
    const bool is_double = d.type == "double";
    if (type != XmlRpc::XmlRpcValue::TypeInt && !(is_double && type == XmlRpc::XmlRpcValue::TypeDouble))
    {
      s << (is_double ? "a number" : "an integer");
      return s.str();
    }
    const double x = type == XmlRpc::XmlRpcValue::TypeInt ? double(int(v)) : double(v);
    const KinectPipelineConfig &lo = KinectPipelineConfig::__getMin__(), &hi = KinectPipelineConfig::__getMax__();
    const double min = is_double ? fieldOf<double>(d, lo) : fieldOf<int>(d, lo);
    const double max = is_double ? fieldOf<double>(d, hi) : fieldOf<int>(d, hi);
    if (x >= min && x <= max)  // false for NaN
      return "";
    s << "a value in [" << min << ", " << max << "]" << unitOf(d.description);
    return s.str();
  }
  if (d.type == "bool" && type != XmlRpc::XmlRpcValue::TypeBoolean)
  {
    s << "true or false";
    return s.str();
  }
  if (d.type == "str" && type != XmlRpc::XmlRpcValue::TypeString)
  {
    s << "a string (quote it in YAML)";
    return s.str();
  }
  return "";
}

/** Levenshtein distance. */
std::size_t editDistance(const std::string& a, const std::string& b)
{
  std::vector<std::size_t> row(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j)
    row[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i)
  {
    std::size_t diagonal = row[0];
    row[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j)
    {
      const std::size_t up = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diagonal + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diagonal = up;
    }
  }
  return row[b.size()];
}

/** "~range_max = 10 (the preset's 4)" when the server's value of a preset field differs from the preset's, else "". */
std::string presetOverride(const ros::NodeHandle& pnh, const ConfigField& f, const Config& preset)
{
  XmlRpc::XmlRpcValue v;
  pnh.getParam(f.name, v);
  Config server = preset;
  bool same = false;
  try
  {
    if (v.getType() == XmlRpc::XmlRpcValue::TypeString && (f.kind == FieldKind::kCurve || f.kind == FieldKind::kChoice))
    {
      f.setText(server, std::string(v));  // compared as parsed: spacing does not count
      same = f.text(server) == f.text(preset);
    }
    else if (v.getType() == XmlRpc::XmlRpcValue::TypeInt || v.getType() == XmlRpc::XmlRpcValue::TypeDouble)
    {
      const double x = v.getType() == XmlRpc::XmlRpcValue::TypeInt ? double(int(v)) : double(v);
      same = std::fabs(x - f.number(preset)) <= 1e-9 * std::max(1.0, std::fabs(x));
    }
  }
  catch (const std::invalid_argument&)
  {
    same = false;  // a bad value: the startup check names it
  }
  if (same)
    return "";
  std::ostringstream o;
  o << "~" << f.name << " = " << describe(v) << " (the preset's: ";
  if (f.kind == FieldKind::kReal || f.kind == FieldKind::kInteger)
    o << f.number(preset);
  else
    o << "'" << f.text(preset) << "'";
  o << ")";
  return o.str();
}
}  // namespace

std::string asParameterNames(std::string message)
{
  for (std::size_t at = message.find("Config."); at != std::string::npos; at = message.find("Config.", at))
    message.replace(at, 7, "~");
  return message;
}

NodeSettings settingsFromConfig(const KinectPipelineConfig& c)
{
  NodeSettings s;
  const std::vector<std::string> problems = settingsProblems(c, s);
  if (!problems.empty())
    throw std::invalid_argument(join(problems, "; "));
  return s;
}

std::vector<std::string> serverParameterProblems(const ros::NodeHandle& pnh, KinectPipelineConfig& config)
{
  config = KinectPipelineConfig::__getDefault__();
  std::vector<std::string> problems;
  for (const auto& d : KinectPipelineConfig::__getParamDescriptions__())
  {
    XmlRpc::XmlRpcValue v;
    if (!pnh.getParam(d->name, v))
      continue;
    const std::string problem = typeOrRangeProblem(*d, v);
    if (problem.empty())
      d->fromServer(pnh, config);
    else
      problems.push_back(problem);
  }
  return problems;
}

NodeSettings startupSettings(const ros::NodeHandle& pnh, const std::string& node_name)
{
  KinectPipelineConfig c;
  std::vector<std::string> problems = serverParameterProblems(pnh, c);
  NodeSettings s;
  for (const std::string& p : settingsProblems(c, s))
    problems.push_back(p);
  if (problems.empty())
    return s;
  std::ostringstream m;
  m << node_name << ": not starting: " << problems.size() << " parameter"
    << (problems.size() == 1 ? " is" : "s are")
    << " invalid (nothing runs on values you did not ask for):\n  " << join(problems, "\n  ")
    << "\nFix them in the params file or the launch arguments; README.md, 'Parameters', lists every parameter with "
       "its unit and range.";
  throw StartupError(m.str());
}

void applySensorModelParameters(const ros::NodeHandle& pnh, const std::string& node_name)
{
  std::string name;
  if (!pnh.getParam("sensor_model", name) || name.empty())
    return;
  Config preset;
  try
  {
    applySensorModel(name, preset);
  }
  catch (const std::invalid_argument& e)
  {
    throw StartupError(node_name + ": not starting: ~" + e.what());
  }
  std::string set;
  std::vector<std::string> overriding;
  for (const std::string& field : sensorModelFields())
  {
    const ConfigField& f = configField(field);
    if (pnh.hasParam(field))
    {
      const std::string o = presetOverride(pnh, f, preset);
      if (!o.empty())
        overriding.push_back(o);
      continue;
    }
    if (f.kind == FieldKind::kReal)
      pnh.setParam(field, f.number(preset));
    else if (f.kind == FieldKind::kInteger)
      pnh.setParam(field, static_cast<int>(f.number(preset)));
    else
      pnh.setParam(field, f.text(preset));
    set += (set.empty() ? "" : ", ") + field;
  }
  ROS_INFO("%s: sensor_model %s (%s): %s from the preset", node_name.c_str(), name.c_str(),
           sensorModel(name).description.c_str(), set.empty() ? "nothing" : set.c_str());
  if (!overriding.empty())
    ROS_WARN("%s: ~sensor_model %s: %s on the parameter server override the preset. If you did not set them, an "
             "earlier run left them there (the node writes every parameter, and a roscore keeps them): delete them "
             "(rosparam delete %s/PARAMETER) or start with kinect_pipeline.launch, which clears them first",
             node_name.c_str(), name.c_str(), join(overriding, ", ").c_str(), pnh.getNamespace().c_str());
}

const std::vector<std::string>& extraParameterNames()
{
  // image_transport: the input transport; sensor_model: the preset, read once at start; diagnostic_period:
  // diagnostic_updater's; startup_error: where the nodelet leaves why it did not start, for the launch file's loader.
  static const std::vector<std::string> names{"image_transport", "sensor_model", "diagnostic_period",
                                              "startup_error"};
  return names;
}

std::string closestParameter(const std::string& name)
{
  // Peer packages' names for what a parameter of ours does (depthimage_to_laserscan, pointcloud_to_laserscan,
  // laserscan_kinect): the meaning decides, not the spelling.
  static const std::map<std::string, std::string> peers{
      {"output_frame_id", "scan_frame"},    {"target_frame", "scan_frame"},   {"frame_id", "scan_frame"},
      {"sensor_mount_height", "sensor_height"}, {"sensor_tilt_angle", "sensor_pitch"},
      {"max_height", "ceiling_height"},     {"concurrency_level", "num_threads"}, {"angle_min", "scan_fov"},
      {"angle_max", "scan_fov"},            {"ground_margin", "threshold_curve"},
  };
  const auto peer = peers.find(name);
  if (peer != peers.end())
    return peer->second;
  std::string best;
  std::size_t best_d = std::string::npos;
  for (const auto& d : KinectPipelineConfig::__getParamDescriptions__())
  {
    const std::size_t e = editDistance(name, d->name);
    if (e < best_d)
    {
      best_d = e;
      best = d->name;
    }
  }
  return best;
}

std::vector<std::string> unknownParameterWarnings(const ros::NodeHandle& pnh)
{
  std::vector<std::string> keys;
  if (!pnh.getParamNames(keys))
    return {};
  const std::string prefix = pnh.getNamespace() + "/";
  const std::vector<std::string>& extra = extraParameterNames();
  std::set<std::string> unknown;
  for (const std::string& key : keys)
  {
    if (key.compare(0, prefix.size(), prefix) != 0)
      continue;
    const std::string top = key.substr(prefix.size(), key.find('/', prefix.size()) - prefix.size());
    if (!top.empty() && !findDescription(top) && std::find(extra.begin(), extra.end(), top) == extra.end())
      unknown.insert(top);
  }
  std::vector<std::string> out;
  for (const std::string& u : unknown)
  {
    const std::string near = closestParameter(u);
    const Description* d = findDescription(near);
    out.push_back("~" + u + " is not a parameter of kinect_pipeline and is ignored; the closest of ours is ~" + near +
                  (d ? ": " + d->description : std::string()) + " (README.md, 'Parameters')");
  }
  return out;
}

}  // namespace kinect_pipeline
