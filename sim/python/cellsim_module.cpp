// The Python API (issue 22, item 3): the project's own objects behind pybind11, nothing
// re-implemented in Python. docs/python.md says how to use it.
//   import cellsim
//   s = cellsim.Scenario("sim/scenarios/plane.yaml")
//   image, truth = s.render("initial")            # H x W x 3 uint8, dict of arrays
//   spots = s.decoder().decode(image)              # dict of arrays: row, col, u, v, off_line, clipped
//   env = cellsim.ServoEnv(s, max_steps=300)       # the Gymnasium API's shape
// Bad input (a wrong dtype or shape, a NaN twist, a bad file) raises ValueError or
// RuntimeError with a one-line message; nothing crashes.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/eval.h>
#include <pybind11/stl.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <memory>
#include <string>

#include "common/strict_yaml.hpp"
#include "servo/node/servo_state_machine.hpp"
#include "sim/cell/build_cell.hpp"
#include "sim/experiment/experiment.hpp"
#include "sim/experiment/servo_env.hpp"
#include "sim/python/gymnasium_layer.hpp"
#include "sim/render/renderer.hpp"

namespace py = pybind11;

namespace {

using U8Array = py::array_t<std::uint8_t, py::array::c_style>;

py::array_t<double> matrix4(const Eigen::Isometry3d& T) {
  py::array_t<double> a({4, 4});
  auto m = a.mutable_unchecked<2>();
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) m(r, c) = T.matrix()(r, c);
  return a;
}

Eigen::Isometry3d pose_of(const py::array_t<double>& a, const std::string& what) {
  if (a.ndim() != 2 || a.shape(0) != 4 || a.shape(1) != 4)
    throw py::value_error(what + ": a pose is a 4 x 4 array (world_T_camera), got shape " + std::to_string(a.ndim()) + "-D");
  auto m = a.unchecked<2>();
  Eigen::Matrix4d M;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) {
      if (!std::isfinite(m(r, c))) throw py::value_error(what + ": the pose holds a non-finite value");
      M(r, c) = m(r, c);
    }
  const Eigen::Matrix3d R = M.topLeftCorner<3, 3>();
  if ((R.transpose() * R - Eigen::Matrix3d::Identity()).norm() > 1e-6 || std::abs(R.determinant() - 1) > 1e-6)
    throw py::value_error(what + ": the pose's rotation is not a rotation matrix");
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = R;
  T.translation() = M.topRightCorner<3, 1>();
  return T;
}

U8Array image_array(const cv::Mat& rgb) {
  U8Array a({rgb.rows, rgb.cols, 3});
  std::memcpy(a.mutable_data(), rgb.data, rgb.total() * 3);
  return a;
}

// An H x W x 3 uint8 array as the decoder takes it (the servo's own checks on sizes apply).
// A crop, a flipped view (img[..., ::-1]) or a Fortran-order array is copied to C order: only
// the dtype is checked (a non-contiguous uint8 array is not an array_t<uint8, c_style>).
cv::Mat image_of(const py::array& a, const std::string& what = "image") {
  if (a.dtype().kind() != 'u' || a.itemsize() != 1)
    throw py::value_error(what + ": dtype must be uint8, got " + std::string(py::str(a.dtype())));
  if (a.ndim() != 3 || a.shape(2) != 3)
    throw py::value_error(what + ": shape must be (height, width, 3), RGB");
  if (a.shape(0) < 1 || a.shape(1) < 1 || a.shape(0) > servo::kMaxImageSide || a.shape(1) > servo::kMaxImageSide)
    throw py::value_error(what + ": each side must be in [1, " + std::to_string(servo::kMaxImageSide) + "] pixels");
  if (static_cast<std::uint64_t>(a.shape(0)) * static_cast<std::uint64_t>(a.shape(1)) > servo::kMaxImagePixels)
    throw py::value_error(what + ": " + std::to_string(a.shape(1)) + " x " + std::to_string(a.shape(0)) +
                          " pixels, more than 4096 x 2304");
  const U8Array c = U8Array::ensure(a);  // C-contiguous (a copy when it was not)
  if (!c) throw py::value_error(what + ": cannot be read as a C-ordered uint8 array");
  return cv::Mat(static_cast<int>(c.shape(0)), static_cast<int>(c.shape(1)), CV_8UC3, const_cast<std::uint8_t*>(c.data()))
      .clone();
}

// A loaded scenario and its compiled cell (meshes, Bullet world, projector).
struct Scenario {
  explicit Scenario(const std::string& file) : cell(sim::build_cell(sim::load_scenario(checked_path(file)))) {}
  // a path with a NUL byte would be cut there by the file system's calls: refused whole
  static const std::string& checked_path(const std::string& file) {
    if (file.find('\0') != std::string::npos) throw py::value_error("file: the path has a NUL byte");
    return file;
  }
  std::shared_ptr<const sim::Cell> cell;

  Eigen::Isometry3d pose(const py::object& p) const {
    if (py::isinstance<py::str>(p)) return sim::resolve_pose(cell->scenario, p.cast<std::string>());
    return pose_of(p.cast<py::array_t<double>>(), "pose");
  }
};

// The servo's configuration for a scenario, as `cellsim experiment` makes it.
servo::ServoConfig servo_config(const Scenario& s, const std::string& model, double z_hat, double gain,
                                const std::string& robust, const std::string& visual_features = "") {
  servo::ServoConfig cfg = experiment::servo_config_for(*s.cell);
  cfg.law.model = control::parse_interaction_model(model);
  // as the CLI's --z-hat: finite, in [0, 100] m, 0 the scenario's desired depth
  if (!(std::isfinite(z_hat) && z_hat >= 0 && z_hat <= 100))
    throw py::value_error("z_hat must be in [0, 100] m (0: the scenario's desired depth), got " + std::to_string(z_hat));
  cfg.law.z_hat_m = z_hat > 0 ? z_hat : experiment::desired_depth(*s.cell);
  if (!(gain > 0 && gain < 100)) throw py::value_error("gain must be in (0, 100)");
  cfg.law.gain = {gain, gain, 0};
  cfg.law.robust = control::parse_robust_estimator(robust);
  cfg.law.features = experiment::visual_features_or_default(visual_features, cfg);  // "": the scenario's
  control::check_options(cfg.law);  // robust weights with the moments: refused here, in one line
  cfg.decoder.epipolar.enabled = false;
  return cfg;
}

// one array of a field of every row
template <typename T, typename Row, typename Get>
py::array_t<T> column(const std::vector<Row>& rows, Get get) {
  py::array_t<T> a(static_cast<py::ssize_t>(rows.size()));
  for (std::size_t i = 0; i < rows.size(); ++i) a.mutable_at(static_cast<py::ssize_t>(i)) = get(rows[i]);
  return a;
}

py::dict truth_dict(const std::vector<sim::SpotTruth>& truth) {
  using T = sim::SpotTruth;
  py::dict d;
  d["row"] = column<int>(truth, [](const T& t) { return t.row; });
  d["col"] = column<int>(truth, [](const T& t) { return t.col; });
  d["visible"] = column<bool>(truth, [](const T& t) { return t.visible; });
  d["u"] = column<double>(truth, [](const T& t) { return t.uv.x(); });
  d["v"] = column<double>(truth, [](const T& t) { return t.uv.y(); });
  d["depth_m"] = column<double>(truth, [](const T& t) { return t.depth_m; });
  return d;
}

// The robot placed at a pose: its links, drawn and lit as `cellsim render` draws them.
sim::LinkPoses links_at(const Scenario& s, const Eigen::Isometry3d& wTc) {
  const std::unique_ptr<sim::Robot> robot = sim::make_robot(*s.cell);
  try {
    robot->reset(wTc);
  } catch (const std::invalid_argument& e) {
    throw py::value_error(s.cell->scenario.file.string() + ": pose: " + e.what());  // the in-collision message names the file
  }
  return robot->world_T_links();
}

// The white reference frame beside frame k's pattern frame, as `cellsim render --white` writes it.
py::array render_white(const Scenario& s, const py::object& pose_spec, std::uint64_t frame) {
  const Eigen::Isometry3d wTc = s.pose(pose_spec);
  const sim::LinkPoses links = links_at(s, wTc);
  return image_array(sim::render_image(*s.cell, wTc, sim::white_frame_seed(sim::frame_seed(s.cell->scenario.seed, frame)),
                                       nullptr, nullptr, &links, sim::Cast::kWhite));
}

py::tuple render(const Scenario& s, const py::object& pose_spec, std::uint64_t frame) {
  const Eigen::Isometry3d wTc = s.pose(pose_spec);
  const sim::LinkPoses links = links_at(s, wTc);
  const cv::Mat rgb =
      sim::render_image(*s.cell, wTc, sim::frame_seed(s.cell->scenario.seed, frame), nullptr, nullptr, &links);
  return py::make_tuple(image_array(rgb), truth_dict(sim::compute_truth(*s.cell, wTc, &links)));
}

py::dict spots_dict(const std::vector<servo::ImageSpot>& spots, int detected) {
  using S = servo::ImageSpot;
  py::dict d;
  d["row"] = column<int>(spots, [](const S& s) { return s.row; });
  d["col"] = column<int>(spots, [](const S& s) { return s.col; });
  d["u"] = column<double>(spots, [](const S& s) { return s.u; });
  d["v"] = column<double>(spots, [](const S& s) { return s.v; });
  // off its id's epipolar line (the frame's own, fitted to its spots): no feature of the law
  d["off_line"] = column<bool>(spots, [](const S& s) { return s.off_line; });
  // named by the grown lattice on a blob smaller than its sources (a clipped footprint): no
  // feature of the law either
  d["clipped"] = column<bool>(spots, [](const S& s) { return s.clipped; });
  d["detected"] = detected;
  return d;
}

// The servo's pipeline: decoding, teaching, one iteration of the control law.
// a scenario's servo configuration, decoding again on each frame's fitted lines or not
servo::ServoConfig with_fitted_lines(servo::ServoConfig cfg, bool fitted_lines) {
  cfg.decoder.epipolar.fitted_lines = fitted_lines;
  return cfg;
}

struct Servo {
  Servo(const Scenario& s, const std::string& model, double z_hat, double gain, const std::string& robust,
        bool fitted_lines = false)
      : scenario(s),
        pipeline(pattern::WindowTable(s.cell->projector->pattern(), {3, 3}),
                 with_fitted_lines(servo_config(s, model, z_hat, gain, robust), fitted_lines)) {}
  Scenario scenario;
  servo::ServoPipeline pipeline;

  // the image's spots, decoded alone or as its ratio to its white frame (None: none)
  std::vector<servo::ImageSpot> locate(const py::array& image, const py::object& white, int* detected) const {
    const cv::Mat rgb = image_of(image);
    if (white.is_none()) return pipeline.locate(rgb, std::nullopt, detected);
    const cv::Mat w = image_of(white.cast<py::array>(), "white");
    if (w.size() != rgb.size()) throw py::value_error("white: its shape must be the image's");
    return pipeline.locate(rgb, std::nullopt, detected, &w);
  }
  py::dict decode(const py::array& image, const py::object& white) const {
    int detected = 0;
    const auto spots = locate(image, white, &detected);
    return spots_dict(spots, detected);
  }
  int teach(const py::array& image, const py::object& white) {
    return pipeline.teach(locate(image, white, nullptr), std::nullopt);
  }
  py::dict step(const py::array& image, const py::object& white) const {
    if (!pipeline.taught()) throw py::value_error("step(): teach() the servo first");
    int detected = 0;
    const servo::StepResult r = pipeline.step(locate(image, white, &detected), std::nullopt);
    py::dict d;
    py::array_t<double> twist(6);
    for (int i = 0; i < 6; ++i) twist.mutable_at(i) = r.control.twist[i];
    d["twist"] = twist;
    d["error_norm"] = r.control.error_norm;
    d["detected"] = r.detected;
    d["decoded"] = r.decoded;
    d["matched"] = static_cast<int>(r.matched.size());
    d["status"] = r.control.reason.empty() ? std::string("servoing") : r.control.reason;
    return d;
  }
};

py::dict run_experiment_dict(const Scenario& s, const std::string& model, double z_hat, double gain, const std::string& robust,
                    int max_iterations, const std::string& features, const std::string& visual_features,
                    bool interior_points, bool fitted_lines, bool white_frame, double white_frame_lead) {
  if (max_iterations < 1 || max_iterations > 100000) throw py::value_error("max_iterations must be in [1, 100000]");
  experiment::ExperimentOptions o;
  o.servo = servo_config(s, model, z_hat, gain, robust, visual_features);
  o.servo.interior_points = interior_points;
  o.servo.decoder.epipolar.fitted_lines = fitted_lines;
  o.source = experiment::parse_feature_source(features);
  if (white_frame && loop::from_truth_alone(o.source))
    throw py::value_error("white_frame needs features='decoded' or 'decoded-ids'");
  if (!(white_frame_lead >= 0 && white_frame_lead <= 1)) throw py::value_error("white_frame_lead must be in [0, 1]");
  if (white_frame_lead > 0 && !white_frame) throw py::value_error("white_frame_lead needs white_frame=True");
  o.white_frame = white_frame;
  o.white_frame_lead = white_frame_lead;
  o.max_iterations = max_iterations;
  // Ctrl-C stops the run at the next round (a signal reaches Python only when it holds the GIL)
  bool interrupted = false;
  o.cancelled = [&interrupted] {
    py::gil_scoped_acquire gil;
    interrupted = interrupted || PyErr_CheckSignals() != 0;
    return interrupted;
  };
  experiment::ExperimentResult r;
  {
    py::gil_scoped_release release;  // a long run: other Python threads go on
    r = experiment::run_experiment(*s.cell, o);
  }
  if (interrupted) throw py::error_already_set();  // the KeyboardInterrupt PyErr_CheckSignals raised
  using I = experiment::IterationRecord;
  const auto& tr = r.trace;
  py::array_t<double> twist({static_cast<py::ssize_t>(tr.size()), py::ssize_t{6}});
  for (std::size_t i = 0; i < tr.size(); ++i)
    for (int k = 0; k < 6; ++k) twist.mutable_at(static_cast<py::ssize_t>(i), k) = tr[i].twist[k];
  py::dict d;
  d["converged"] = r.converged;
  d["stop_reason"] = r.stop_reason;
  d["iterations"] = r.iterations;
  d["decoded_desired"] = r.decoded_desired;
  d["decoded_initial"] = r.decoded_initial;
  d["final_translation_error_m"] = r.final_translation_error_m;
  d["final_rotation_error_deg"] = r.final_rotation_error_deg;
  d["path_length_m"] = r.path_length_m;
  d["straight_line_m"] = r.straight_line_m;
  d["condition_median"] = r.condition_median;  // of the law's L over the run (cellsim experiment prints it)
  d["condition_max"] = r.condition_max;
  d["t"] = column<double>(tr, [](const I& i) { return i.t_s; });
  d["twist"] = twist;
  d["error_norm"] = column<double>(tr, [](const I& i) { return i.error_norm; });
  d["translation_error_m"] = column<double>(tr, [](const I& i) { return i.translation_error_m; });
  d["rotation_error_deg"] = column<double>(tr, [](const I& i) { return i.rotation_error_deg; });
  d["decoded"] = column<int>(tr, [](const I& i) { return i.decoded; });
  d["matched"] = column<int>(tr, [](const I& i) { return i.matched; });
  // the points the law took off their spot's centre (the simulator's truth; decoded features)
  d["off_centre"] = column<int>(tr, [](const I& i) { return i.off_centre; });
  d["off_centre_max"] = r.off_centre_max;
  d["condition"] = column<double>(tr, [](const I& i) { return i.condition; });
  return d;
}

// The environment, in the Gymnasium API's shape (without depending on Gymnasium).
struct Env {
  Env(const Scenario& s, const std::string& observation, int max_steps, const std::string& model, double z_hat,
      double gain, const std::string& robust, bool white_frame, const std::string& features)
      : scenario(s), images(observation == "image") {
    if (observation != "features" && observation != "image")
      throw py::value_error("observation must be 'features' or 'image', got '" + observation + "'");
    experiment::EnvOptions o;
    o.source = experiment::parse_feature_source(features);
    // the truth's sources render no frame: nothing to observe as an image, nothing to divide
    if (loop::from_truth_alone(o.source) && (images || white_frame))
      throw py::value_error(std::string(images ? "observation='image'" : "white_frame") +
                            " needs features='decoded' or 'decoded-ids' (the truth renders no frame)");
    o.servo = servo_config(s, model, z_hat, gain, robust);
    o.servo.white_frame = white_frame;  // each frame decoded with its white reference frame
    o.max_steps = max_steps;
    o.images = true;  // the observation in image mode, render() in both
    env = std::make_unique<experiment::ServoEnv>(*s.cell, o);
    rows = s.cell->projector->pattern().rows;
    cols = s.cell->projector->pattern().cols;
  }
  Scenario scenario;
  bool images;
  std::unique_ptr<experiment::ServoEnv> env;
  int rows = 0, cols = 0;
  cv::Mat last_image;

  // One row per pattern id, row-major, whatever the frame shows (a fixed shape, as Gymnasium
  // wants): (x, y, x*, y*, seen), normalised image coordinates; zeros and seen = 0 where the id
  // is not matched to s* in this frame. The image mode: the H x W x 3 frame.
  py::object obs(const experiment::EnvObservation& o) {
    last_image = o.image;
    if (images) {
      const auto& k = scenario.cell->scenario.camera.intrinsics;
      return o.image.empty() ? image_array(cv::Mat(k.height, k.width, CV_8UC3, cv::Scalar::all(0)))
                             : image_array(o.image);
    }
    py::array_t<double> f({static_cast<py::ssize_t>(rows) * cols, py::ssize_t{5}});
    std::fill(f.mutable_data(), f.mutable_data() + f.size(), 0.0);
    for (const auto& m : o.matched) {
      if (m.row < 0 || m.col < 0 || m.row >= rows || m.col >= cols) continue;
      const auto r = static_cast<py::ssize_t>(m.row) * cols + m.col;
      f.mutable_at(r, 0) = m.x;
      f.mutable_at(r, 1) = m.y;
      f.mutable_at(r, 2) = m.x_star;
      f.mutable_at(r, 3) = m.y_star;
      f.mutable_at(r, 4) = 1.0;
    }
    return f;
  }
  py::object frame() const { return last_image.empty() ? py::object(py::none()) : py::object(image_array(last_image)); }
  py::tuple speed_limits() const {
    const auto& r = scenario.cell->scenario.robot;
    return py::make_tuple(r.max_linear_mps, r.max_angular_radps);
  }
  py::dict info(const experiment::EnvStep& s) const {
    const auto& o = s.observation;
    py::array_t<int> ids({static_cast<py::ssize_t>(o.matched.size()), py::ssize_t{2}});
    for (std::size_t i = 0; i < o.matched.size(); ++i) {
      ids.mutable_at(static_cast<py::ssize_t>(i), 0) = o.matched[i].row;
      ids.mutable_at(static_cast<py::ssize_t>(i), 1) = o.matched[i].col;
    }
    py::dict d;
    d["error_norm"] = o.error_norm;
    d["detected"] = o.detected;
    d["decoded"] = o.decoded;
    d["ids"] = ids;
    d["servo_state"] = o.servo_state;
    d["camera_pose"] = matrix4(o.world_T_camera);
    d["translation_error_m"] = o.translation_error_m;
    d["rotation_error_deg"] = o.rotation_error_deg;
    d["time_s"] = o.time_s;
    d["steps"] = env->steps();
    d["reason"] = s.reason;
    d["limited"] = o.limited;
    return d;
  }
  // seed: None, or a whole number 0 .. 2**64 - 1 (pybind's own conversion error named no
  // argument); options: a dict of known keys only (an unknown one was ignored)
  py::tuple reset(const py::object& seed, const std::optional<py::dict>& options) {
    std::optional<std::uint64_t> draw;
    if (!seed.is_none()) {
      const bool whole = py::isinstance<py::int_>(seed) && !py::isinstance<py::bool_>(seed);
      if (!whole || seed < py::int_(0) || seed > py::int_(std::numeric_limits<std::uint64_t>::max()))
        throw py::value_error("reset: seed must be None or a whole number from 0 to 2**64 - 1, got " +
                              common::printable(py::str(py::repr(seed)).cast<std::string>(), 60));
      draw = seed.cast<std::uint64_t>();
    }
    std::optional<Eigen::Isometry3d> initial;
    if (options) {
      for (const auto& [key, value] : *options) {
        const std::string k = py::str(key).cast<std::string>();
        if (k != "initial_pose")
          throw py::value_error("reset: unknown option '" + common::printable(k, 60) + "' (known: initial_pose)");
      }
      if (options->contains("initial_pose")) initial = scenario.pose((*options)["initial_pose"]);
    }
    const experiment::EnvStep s = env->reset(draw, initial);
    return py::make_tuple(obs(s.observation), info(s));
  }
  py::tuple step(const py::object& action) {
    const auto a = py::array_t<double, py::array::forcecast>::ensure(action);
    if (!a || a.ndim() != 1 || a.shape(0) != 6)
      throw py::value_error("twist: 6 numbers (vx vy vz wx wy wz, m/s and rad/s, camera frame)");
    control::Vector6d t;
    for (int i = 0; i < 6; ++i) t[i] = a.at(i);
    const experiment::EnvStep s = env->step(t);
    return py::make_tuple(obs(s.observation), s.reward, s.terminated, s.truncated, info(s));
  }
};

}  // namespace

PYBIND11_MODULE(cellsim, m) {
  m.doc() = "The coded-light visual-servoing cell: scenarios, rendering, decoding, the servo, experiments, "
            "and an environment in the Gymnasium API's shape (docs/python.md)";
  // the project's one-line errors, as Python exceptions
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const std::invalid_argument& e) {
      PyErr_SetString(PyExc_ValueError, e.what());
    } catch (const std::logic_error& e) {
      PyErr_SetString(PyExc_RuntimeError, e.what());
    }
  });
  py::class_<Scenario>(m, "Scenario", "a scenario file, loaded and compiled (meshes, Bullet world, projector)")
      .def(py::init<const std::string&>(), py::arg("file"))
      .def_property_readonly("name", [](const Scenario& s) { return s.cell->scenario.name; })
      .def_property_readonly("dt", [](const Scenario& s) { return s.cell->scenario.dt_s; })
      .def_property_readonly("seed", [](const Scenario& s) { return s.cell->scenario.seed; })
      .def_property_readonly("width", [](const Scenario& s) { return s.cell->scenario.camera.intrinsics.width; })
      .def_property_readonly("height", [](const Scenario& s) { return s.cell->scenario.camera.intrinsics.height; })
      .def_property_readonly("desired_pose", [](const Scenario& s) { return matrix4(s.cell->scenario.world_T_desired); })
      .def_property_readonly("initial_pose", [](const Scenario& s) { return matrix4(s.cell->scenario.world_T_initial()); })
      .def("render_white", &render_white, py::arg("pose") = "desired", py::arg("frame") = 0,
           "the white reference frame beside render()'s image (H x W x 3 uint8): the projector casting white, as "
           "`cellsim render --white` writes it")
      .def("render", &render, py::arg("pose") = "desired", py::arg("frame") = 0,
           "(image H x W x 3 uint8, truth dict of arrays) at a pose: 'desired', 'initial', \"x y z rx ry rz\" (cm, "
           "deg) or a 4 x 4 world_T_camera; frame k's noise, as `cellsim render --frame k`")
      .def("decoder",
           [](const Scenario& s, bool fitted_lines) {
             return std::make_unique<Servo>(s, "desired-constant-depth", 0, 0.5, "none", fitted_lines);
           },
           py::arg("fitted_lines") = false,
           "a servo of the scenario's pattern and camera, for decode() (fitted_lines: decode each frame again on the "
           "epipolar lines fitted to its first decoding's spots, as --fitted-lines)");
  py::class_<Servo>(m, "Servo", "the servo's pipeline: decode, teach, one control-law iteration")
      .def(py::init<const Scenario&, const std::string&, double, double, const std::string&>(), py::arg("scenario"),
           py::arg("model") = "desired-constant-depth", py::arg("z_hat") = 0.0, py::arg("gain") = 0.5,
           py::arg("robust") = "none")
      .def("decode", &Servo::decode, py::arg("image"), py::arg("white") = py::none(),
           "spots of an H x W x 3 uint8 RGB image: dict of row, col, u, v (white: its white reference frame, "
           "Scenario.render_white, the image decoded as their ratio)")
      .def("teach", &Servo::teach, py::arg("image"), py::arg("white") = py::none(),
           "the features of this image become s*; returns how many")
      .def("step", &Servo::step, py::arg("image"), py::arg("white") = py::none(),
           "one iteration: dict of twist (6), error_norm, decoded, matched");
  m.def("experiment", &run_experiment_dict, py::arg("scenario"), py::arg("model") = "desired-constant-depth",
        py::arg("z_hat") = 0.0, py::arg("gain") = 0.5, py::arg("robust") = "none", py::arg("max_iterations") = 400,
        py::arg("features") = "decoded", py::arg("visual_features") = "", py::arg("interior_points") = false,
        py::arg("fitted_lines") = false, py::arg("white_frame") = false, py::arg("white_frame_lead") = 0.0,
        "the in-process closed loop, as `cellsim experiment`: a dict of the result and the trace's columns "
        "(features: where the spots come from, decoded | ideal | resolved | decoded-ids; visual_features: what the law servoes on, points | "
        "moments | surface | plane; empty: the scenario's, points, or plane with the projector on the camera; "
        "interior_points: servo on the matched spots whose four pattern neighbours are matched too, as "
        "--interior-points; fitted_lines: decode each frame again on its fitted epipolar lines, as --fitted-lines; "
        "white_frame: the white reference frame beside each frame, taken white_frame_lead of a frame period before "
        "it, as --white-frame and --white-frame-lead)");
  py::class_<Env>(m, "_ServoEnvCore",
                  "the environment's engine (ServoEnv, defined below in Python, is the public face)")
      .def(py::init<const Scenario&, const std::string&, int, const std::string&, double, double, const std::string&,
                    bool, const std::string&>(),
           py::arg("scenario"), py::arg("observation") = "features", py::arg("max_steps") = 300,
           py::arg("model") = "desired-constant-depth", py::arg("z_hat") = 0.0, py::arg("gain") = 0.5,
           py::arg("robust") = "none", py::arg("white_frame") = false, py::arg("features") = "decoded")
      .def("reset", &Env::reset, py::arg("seed") = py::none(), py::arg("options") = py::none())
      .def("step", &Env::step, py::arg("twist"))
      .def("frame", &Env::frame)
      .def_property_readonly("pattern_shape", [](const Env& e) { return py::make_tuple(e.rows, e.cols); })
      .def_property_readonly("speed_limits", &Env::speed_limits);
  m.attr("__version__") = CELL_VERSION;
  py::exec(cellsim_python::kGymnasiumLayer, m.attr("__dict__"));
}
