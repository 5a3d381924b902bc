// numpy <-> cv::Mat conversions of the binding (arrays.h).
#include "arrays.h"

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <sstream>

namespace kinect_pipeline::python
{

int cvTypeOf(const py::dtype& dt)
{
  // By kind and size, not identity: '<u2' read from a buffer is uint16 too.
  const char kind = dt.kind();
  const auto size = dt.itemsize();
  if (kind == 'u' && size == 1)
    return CV_8UC1;
  if (kind == 'u' && size == 2)
    return CV_16UC1;
  if (kind == 'f' && size == 4)
    return CV_32FC1;
  return -1;
}

int cvTypeOf(Encoding e)
{
  switch (e)
  {
    case Encoding::kMono8:
      return CV_8UC1;
    case Encoding::kMono16:
      return CV_16UC1;
    case Encoding::kFloat32:
      break;
  }
  return CV_32FC1;
}

std::string typeName(const py::handle& obj) { return py::str(py::type::handle_of(obj).attr("__name__")); }

namespace
{
[[noreturn]] void wrongType(const py::handle& v, const std::string& what, const char* expected)
{
  throw py::type_error(what + " = " + std::string(py::repr(v)) + " (" + typeName(v) + "): expected " + expected);
}
}  // namespace

double numberOf(const py::handle& v, const std::string& what)
{
  // PyNumber_Check: int, float, bool, numpy scalars; not str, None, lists (py::cast<double> reports those as an
  // unnamed RuntimeError, or, through float(), takes "1.0").
  if (py::isinstance<py::str>(v) || !PyNumber_Check(v.ptr()) || py::hasattr(v, "__len__"))
    wrongType(v, what, "a number");
  try
  {
    return py::cast<double>(v);
  }
  catch (const py::cast_error&)
  {
    wrongType(v, what, "a number");
  }
}

bool flagOf(const py::handle& v, const std::string& what)
{
  const bool numpy_bool = py::hasattr(v, "dtype") && !py::hasattr(v, "__len__") &&
                          py::str(v.attr("dtype").attr("kind")).cast<std::string>() == "b";
  if (!PyBool_Check(v.ptr()) && !numpy_bool)
    wrongType(v, what, "True or False");
  return py::cast<bool>(v);
}

namespace
{
/** @throw py::value_error unless @p arr is 2-D with at least one pixel. */
void checkShape(const py::array& arr, const char* what)
{
  std::ostringstream s;
  if (arr.ndim() != 2)
    s << what << ": " << arr.ndim() << "-D array: expected a 2-D (height, width) depth image";
  else if (arr.shape(0) == 0 || arr.shape(1) == 0)
    s << what << ": empty array of shape (" << arr.shape(0) << ", " << arr.shape(1) << ")";
  else
    return;
  throw py::value_error(s.str());
}
}  // namespace

cv::Mat asMat(const py::handle& obj, const char* what, py::object& keep, int* cv_type)
{
  if (!py::isinstance<py::array>(obj))
    throw py::type_error(std::string(what) + ": expected a numpy array, got " + typeName(obj));
  py::array arr = py::reinterpret_borrow<py::array>(obj);
  const int type = cvTypeOf(arr.dtype());
  if (type < 0)
    throw py::type_error(std::string(what) + ": dtype " + std::string(py::str(arr.dtype())) +
                         ": expected uint8 (normalised), uint16 (mm) or float32 (m)");
  checkShape(arr, what);
  const auto item = static_cast<py::ssize_t>(arr.itemsize());
  if (!py::cast<bool>(arr.dtype().attr("isnative")))
    arr = py::array::ensure(arr.attr("astype")(arr.dtype().attr("newbyteorder")("=")));
  if (arr.strides(1) != item || arr.strides(0) < item * arr.shape(1))
    arr = py::array::ensure(py::module_::import("numpy").attr("ascontiguousarray")(arr));
  keep = arr;
  if (cv_type)
    *cv_type = type;
  return cv::Mat(static_cast<int>(arr.shape(0)), static_cast<int>(arr.shape(1)), type,
                 const_cast<void*>(arr.data()), static_cast<std::size_t>(arr.strides(0)));
}

py::array matToArray(const cv::Mat& m)
{
  py::dtype dt = m.type() == CV_8UC1    ? py::dtype::of<std::uint8_t>()
                 : m.type() == CV_16UC1 ? py::dtype::of<std::uint16_t>()
                 : m.type() == CV_16SC1 ? py::dtype::of<std::int16_t>()
                                        : py::dtype::of<float>();
  py::array out(dt, {m.rows, m.cols});
  for (int r = 0; r < m.rows; ++r)
    std::memcpy(static_cast<char*>(out.mutable_data(r, 0)), m.ptr(r), m.cols * m.elemSize());
  return out;
}

py::array_t<float> vecToArray(const std::vector<float>& v)
{
  py::array_t<float> a(static_cast<py::ssize_t>(v.size()));
  std::copy(v.begin(), v.end(), a.mutable_data());
  return a;
}

py::buffer_info asBytes(const py::object& obj, const char* what, py::object& keep)
{
  const char* expected = ": expected bytes, bytearray, memoryview or a 1-D uint8 numpy array";
  keep = obj;
  if (py::isinstance<py::array>(obj))
  {
    py::array a = py::reinterpret_borrow<py::array>(obj);
    if (a.ndim() != 1 || a.dtype().kind() != 'u' || a.itemsize() != 1)
      throw py::type_error(std::string(what) + ": " + std::to_string(a.ndim()) + "-D array of dtype " +
                           std::string(py::str(a.dtype())) + expected);
    keep = py::module_::import("numpy").attr("ascontiguousarray")(a);
  }
  else if (!py::isinstance<py::bytes>(obj) && !py::isinstance<py::bytearray>(obj) &&
           !py::isinstance<py::memoryview>(obj))
  {
    throw py::type_error(std::string(what) + ": " + typeName(obj) + expected);
  }
  py::buffer_info info = py::reinterpret_borrow<py::buffer>(keep).request();
  if (info.itemsize != 1 || info.ndim != 1 || (info.shape[0] > 1 && info.strides[0] != 1))
    throw py::type_error(std::string(what) + ": a " + std::to_string(info.ndim) + "-D view of " +
                         std::to_string(info.itemsize) + "-byte items" + expected + " (contiguous)");
  return info;
}

FloatImage metresImage(const py::handle& obj, const char* what)
{
  if (py::isinstance<py::array>(obj))
  {
    const py::dtype dt = py::reinterpret_borrow<py::array>(obj).dtype();
    const std::string name = py::str(static_cast<const py::handle&>(dt));
    if (dt.kind() != 'f')
      throw py::type_error(std::string(what) + ": a " + name +
                           " array: expected float32 metres (an integer depth is in sensor units: for millimetres "
                           "pass depth.astype(np.float32) / 1000)");
    if (dt.itemsize() != 4)  // float64 is not narrowed silently; float16 is widened by the caller too
      throw py::type_error(std::string(what) + ": a " + name +
                           " array: expected float32 metres (pass depth.astype(np.float32))");
  }
  auto a = FloatImage::ensure(obj);
  if (!a)
    throw py::type_error(std::string(what) + ": " + typeName(obj) + ": expected a 2-D float32 array [m]");
  return a;
}

namespace
{
void checkFloatImage(const FloatImage& depth)
{
  if (depth.ndim() != 2)
    throw py::value_error("depth: expected a 2-D float32 array [m]");
}
}  // namespace

cv::Mat floatImage(const FloatImage& depth)
{
  checkFloatImage(depth);
  return cv::Mat(static_cast<int>(depth.shape(0)), static_cast<int>(depth.shape(1)), CV_32FC1,
                 const_cast<float*>(depth.data()));
}

py::array_t<float> copyOf(const FloatImage& depth)
{
  checkFloatImage(depth);
  py::array_t<float> out({depth.shape(0), depth.shape(1)});
  std::memcpy(out.mutable_data(), depth.data(), depth.nbytes());
  return out;
}

}  // namespace kinect_pipeline::python
