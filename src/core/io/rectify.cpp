#include "kinect_pipeline/io/rectify.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <sstream>
#include <stdexcept>
#include <string>

namespace kinect_pipeline
{
namespace
{
enum class Model
{
  kNone,
  kRadialTangential,  // plumb_bob, rational_polynomial
  kEquidistant,
};

[[noreturn]] void refuse(const std::string& model, const std::vector<double>& D, const std::string& expected)
{
  std::ostringstream s;
  s << "camera_info distortion_model '" << model << "', D = [";
  for (std::size_t i = 0; i < D.size(); ++i)
    s << (i ? ", " : "") << D[i];
  s << "]: expected " << expected;
  throw std::invalid_argument(s.str());
}

// The model, and D padded to the eight coefficients of the radial-tangential model (or the four of the
// equidistant one).
Model modelOf(const std::string& model, const std::vector<double>& D, std::vector<double>& k)
{
  if (std::any_of(D.begin(), D.end(), [](double v) { return !std::isfinite(v); }))
    refuse(model, D, "finite coefficients");
  if (std::all_of(D.begin(), D.end(), [](double v) { return v == 0.0; }))
    return Model::kNone;
  k = D;
  if (model == "plumb_bob" && (D.size() == 4 || D.size() == 5))
  {
    k.resize(8, 0.0);
    return Model::kRadialTangential;
  }
  if (model == "rational_polynomial" && D.size() == 8)
    return Model::kRadialTangential;
  if (model == "equidistant" && D.size() == 4)
    return Model::kEquidistant;
  refuse(model, D,
         "plumb_bob (4 or 5 coefficients), rational_polynomial (8) or equidistant (4), or all coefficients 0 (no "
         "distortion)");
}

// out = raw at each pixel's offset, 0 where that is -1; one thread (the node's threads are its own to set).
template <typename T>
void gather(const cv::Mat& offsets, const cv::Mat& raw, cv::Mat& out)
{
  const std::int32_t* off = offsets.ptr<std::int32_t>();
  const T* src = raw.ptr<T>();
  T* o = out.ptr<T>();
  for (std::size_t i = 0, n = out.total(); i < n; ++i)
  {
    const T v = src[std::max(off[i], 0)];
    o[i] = off[i] < 0 ? T(0) : v;
  }
}

// Where the lens puts the ray of normalised coordinates (x, y): the distorted normalised coordinates.
cv::Point2d distort(Model m, const std::vector<double>& k, double x, double y)
{
  if (m == Model::kEquidistant)
  {
    const double r = std::hypot(x, y);
    const double th = std::atan(r), t2 = th * th;
    const double thd = th * (1.0 + t2 * (k[0] + t2 * (k[1] + t2 * (k[2] + t2 * k[3]))));
    const double s = r > 1e-12 ? thd / r : 1.0;
    return {x * s, y * s};
  }
  const double r2 = x * x + y * y;
  const double radial = (1.0 + r2 * (k[0] + r2 * (k[1] + r2 * k[4]))) / (1.0 + r2 * (k[5] + r2 * (k[6] + r2 * k[7])));
  return {x * radial + 2.0 * k[2] * x * y + k[3] * (r2 + 2.0 * x * x),
          y * radial + k[2] * (r2 + 2.0 * y * y) + 2.0 * k[3] * x * y};
}
}  // namespace

DepthRectifier::DepthRectifier(const Camera& c, const std::string& model, const std::vector<double>& D)
  : width_(c.width), height_(c.height)
{
  std::vector<double> k;
  const Model m = modelOf(model, D, k);
  identity_ = m == Model::kNone;
  if (identity_)
    return;
  map_.create(height_, width_, CV_32SC1);
  long outside = 0;
  for (int v = 0; v < height_; ++v)
    for (int u = 0; u < width_; ++u)
    {
      const cv::Point2d d = distort(m, k, (u - c.cx) / c.fx, (v - c.cy) / c.fy);
      const double ur = c.fx * d.x + c.cx, vr = c.fy * d.y + c.cy;
      max_shift_ = std::max(max_shift_, std::hypot(ur - u, vr - v));
      const bool in = ur > -0.5 && ur < width_ - 0.5 && vr > -0.5 && vr < height_ - 0.5;
      outside += in ? 0 : 1;
      const int ui = static_cast<int>(std::lround(ur)), vi = static_cast<int>(std::lround(vr));
      map_.at<std::int32_t>(v, u) = in ? vi * width_ + ui : -1;  // -1: outside, no measurement
    }
  outside_ = static_cast<double>(outside) / (static_cast<double>(width_) * height_);
}

void DepthRectifier::apply(const cv::Mat& raw, cv::Mat& out) const
{
  if (raw.cols != width_ || raw.rows != height_)
  {
    std::ostringstream s;
    s << "depth image " << raw.cols << "x" << raw.rows << " to rectify: expected its camera's " << width_ << "x"
      << height_;
    throw std::invalid_argument(s.str());
  }
  if (identity_)
    return raw.copyTo(out);
  const cv::Mat src = raw.isContinuous() ? raw : raw.clone();  // the offsets are of a continuous image
  out.create(raw.size(), raw.type());
  switch (raw.type())
  {
    case CV_8UC1:
      return gather<std::uint8_t>(map_, src, out);
    case CV_16UC1:
      return gather<std::uint16_t>(map_, src, out);
    case CV_32FC1:
      return gather<float>(map_, src, out);
    default:
      throw std::invalid_argument("depth image to rectify: expected 8UC1, 16UC1 or 32FC1");
  }
}

bool CameraLens::stereo() const
{
  const bool set = std::any_of(R.begin(), R.end(), [](double v) { return v != 0.0; });
  for (std::size_t i = 0; set && i < R.size(); ++i)
    if (std::fabs(R[i] - (i % 4 == 0 ? 1.0 : 0.0)) > 1e-9)
      return true;
  return false;
}

bool rectifyWanted(const std::string& mode, const std::string& image_topic, const DepthRectifier& rectifier,
                   bool stereo, std::string& why)
{
  if (mode != "auto" && mode != "always" && mode != "never")
    throw std::invalid_argument("rectify = '" + mode + "': expected auto, always or never");
  if (mode == "never")
    why = "no (rectify never)";
  else if (rectifier.identity())
    why = "no (the camera_info has no distortion)";
  else
  {
    std::string name = image_topic;
    for (const char* transport : {"/compressedDepth", "/compressed"})
    {
      const std::string t(transport);
      if (name.size() > t.size() && name.compare(name.size() - t.size(), t.size(), t) == 0)
        name.resize(name.size() - t.size());
    }
    name = name.substr(name.find_last_of('/') + 1);
    if (mode == "auto" && name.find("rect") != std::string::npos)
      why = "no (the topic's name says it is rectified; rectify always to rectify it)";
    else if (mode == "auto" && stereo)
      why = "no (the camera_info's R rotates: a stereo camera's, whose depth images are rectified; rectify always to "
            "rectify them)";
    else
    {
      std::ostringstream s;
      s.precision(3);
      s << "yes (pixels move up to " << rectifier.maxShift() << " px" << (mode == "auto" ? "; rectify never if the "
        "images are rectified already)" : ")");
      why = s.str();
      return true;
    }
  }
  return false;
}

const cv::Mat& TopicRectification::apply(const std::string& mode, const std::string& image_topic, const Camera& camera,
                                         const CameraLens& lens, const cv::Mat& depth)
{
  anew_ = !rectifier_ || mode != mode_ || image_topic != topic_ || camera != camera_ || lens.model != lens_.model ||
          lens.D != lens_.D || lens.R != lens_.R;
  if (anew_)
  {
    rectifier_.reset();
    // A distortion is looked at only where the mode may want it: "never" takes the images as they are.
    const DepthRectifier r = mode == "never" ? DepthRectifier(camera, "", {}) : DepthRectifier(camera, lens.model, lens.D);
    wanted_ = rectifyWanted(mode, image_topic, r, lens.stereo(), why_);
    rectifier_.emplace(r);
    mode_ = mode;
    topic_ = image_topic;
    camera_ = camera;
    lens_ = lens;
  }
  if (!wanted_)
    return depth;
  rectifier_->apply(depth, out_);
  return out_;
}

}  // namespace kinect_pipeline
