// Seeded mutation fuzzing of every reader of untrusted input: the decoder, the pattern reader,
// the scenario reader, the mesh check, the generated CDR deserialisers of every topic type,
// and each DDS message handler (the two state machines the services feed). A refusal (an exception, a rejected message) is the expected outcome;
// a crash, a sanitizer report or a hang is a defect. ctest runs each target for a bounded
// number of inputs; bin/fuzz runs them for long under AddressSanitizer and UBSan.
//
//   fuzz_targets --target decoder|pattern|scenario|mesh|urdf|cell|servo|cdr|campaign|mcap --iterations N [--seconds S] [--seed K]
#include <cmath>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <unistd.h>

#include "foxglove/websocket.hpp"
#include "mcap/mcap_reader.hpp"
#include "cell_msgsPubSubTypes.h"
#include "geometry_msgsPubSubTypes.h"
#include "sensor_msgsPubSubTypes.h"
#include "dds/topics.hpp"
#include "servo/service/servo_replay.hpp"
#include "servo/node/servo_state_machine.hpp"
#include "servo/pattern/pattern_file.hpp"
#include "sim/arm/arm_robot.hpp"
#include "sim/cell/build_cell.hpp"
#include "sim/session/cell_state_machine.hpp"
#include "sim/experiment/campaign.hpp"
#include "sim/experiment/experiment.hpp"
#include "sim/render/renderer.hpp"
#include "sim/scene/mesh_check.hpp"
#include "sim/scene/triangle_mesh.hpp"

namespace {

const std::string kSrc = CELL_SOURCE_DIR;

std::string read(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(f), {}};
}

// One mutation step on bytes: flip, insert, delete, duplicate a run, or splice an
// interesting value (boundaries, huge numbers, NaN) in.
void mutate(std::string& s, std::mt19937_64& rng) {
  static const char* tokens[] = {"1e300", "-1e300", "nan", ".nan", "inf", "0", "-1", "4294967295", "2147483648",
                                 "1e-300", "&a", "*a", "[", "]", "{", "}", ":", "\n", "\x00", "\xff", "99999999999"};
  std::uniform_int_distribution<int> op(0, 5);
  const auto at = [&](std::size_t n) { return n == 0 ? std::size_t{0} : std::uniform_int_distribution<std::size_t>(0, n - 1)(rng); };
  switch (op(rng)) {
    case 0:
      if (!s.empty()) s[at(s.size())] ^= static_cast<char>(1 << (rng() % 8));
      break;
    case 1: s.insert(at(s.size() + 1), 1, static_cast<char>(rng() % 256)); break;
    case 2:
      if (!s.empty()) s.erase(at(s.size()), 1 + at(16));
      break;
    case 3:
      if (!s.empty() && s.size() < (1u << 20)) {
        const std::size_t a = at(s.size());
        s.insert(at(s.size() + 1), s.substr(a, 1 + at(64)));
      }
      break;
    case 4: {
      const std::string t = tokens[at(sizeof tokens / sizeof *tokens)];
      s.insert(at(s.size() + 1), t.empty() ? std::string(1, '\0') : t);
      break;
    }
    default:
      if (!s.empty()) {
        // replace a number-looking run with an interesting value
        const std::size_t a = at(s.size());
        std::size_t b = a;
        while (b < s.size() && (std::isdigit(static_cast<unsigned char>(s[b])) || s[b] == '.')) ++b;
        s.replace(a, b - a, tokens[at(9)]);
      }
  }
}

std::string mutated(const std::string& seed, std::mt19937_64& rng) {
  std::string s = seed;
  const int n = 1 + static_cast<int>(rng() % 8);
  for (int i = 0; i < n; ++i) mutate(s, rng);
  return s;
}

double uniform_extreme(std::mt19937_64& rng) {
  static const double v[] = {0, -0.0, 1, -1, 1e300, -1e300, 1e-300, std::nan(""), INFINITY, -INFINITY, 0.04, 0.5};
  if (rng() % 3 == 0) return v[rng() % (sizeof v / sizeof *v)];
  return std::uniform_real_distribution<double>(-2, 2)(rng);
}

struct Target {
  virtual ~Target() = default;
  virtual void one(std::mt19937_64& rng) = 0;
};

struct PatternTarget : Target {
  std::string seed = read(kSrc + "/servo/pattern/data/marray_20x20_k3_w3.txt");
  void one(std::mt19937_64& rng) override {
    try {
      const pattern::MArray a = pattern::parse_marray(mutated(seed, rng), "fuzz");
      pattern::check_window_property(a, {3, 3});
      if (a.rows >= 3 && a.cols >= 3) pattern::WindowTable t(a, {3, 3});
    } catch (const std::exception&) {
    }
  }
};

struct ScenarioTarget : Target {
  std::string seed = read(kSrc + "/sim/scenarios/cylinder.yaml");
  std::filesystem::path file = std::filesystem::temp_directory_path() / ("fuzz_scenario_" + std::to_string(getpid()) + ".yaml");
  ScenarioTarget() {
    // issue 13's sections, so mutations reach their readers and the draw
    seed += "errors: {focal_pct: 1, principal_point_px: 2, projector_rotation_deg: 0.5, hand_eye_position_mm: 3, "
            "link_length_pct: 0.5, joint_offset_deg: 0.1, seed: 4}\n"
            "latency: {acquisition_frames: 1, processing_frames: 2, actuation_s: 0.01}\n";
  }
  ~ScenarioTarget() override { std::filesystem::remove(file); }
  void one(std::mt19937_64& rng) override {
    // mutated before the paths are made absolute: the inputs do not depend on where the
    // repository lies, so a seed finds the same inputs on every machine
    std::string text = mutated(seed, rng);
    for (std::size_t p = 0; (p = text.find("../../", p)) != std::string::npos; p += kSrc.size() + 1)
      text.replace(p, 6, kSrc + "/");
    std::ofstream(file, std::ios::binary) << text;
    try {
      const sim::Scenario s = sim::load_scenario(file);
      sim::resolve_pose(s, "initial");
      const sim::DrawnErrors d = sim::scenario_errors(s);
      if (!std::isfinite(d.fx_scale) || !d.projector_delta.matrix().allFinite()) std::abort();
    } catch (const std::exception&) {
    }
  }
};

// URDF text: the shipped arm's file, mutated (numbers, tokens, XML structure), read and
// then put through kinematics and a Bullet arm's first steps.
struct UrdfTarget : Target {
  std::string seed = read(kSrc + "/sim/robots/ur5e/ur5e.urdf");
  std::filesystem::path file = std::filesystem::temp_directory_path() / ("fuzz_urdf_" + std::to_string(getpid()) + ".urdf");
  sim::World empty;
  UrdfTarget() = default;
  ~UrdfTarget() override { std::filesystem::remove(file); }
  void one(std::mt19937_64& rng) override {
    static const char* xml[] = {"<", ">", "/>", "</link>", "<link name='x'>", "<joint name='j' type='revolute'>",
                                "<!DOCTYPE r>", "<!--", "<![CDATA[", "\"", "<x><x><x><x><x><x><x><x>", "&amp;",
                                "type='prismatic'", "type='floating'", "<limit/>", "<axis xyz='0 0 0'/>",
                                // geometry (issue 18, item 14): broken origins, sizes and scales
                                "<visual><origin rpy='nan 0 0'/><geometry><box size='0.1 0.1 0.1'/></geometry></visual>",
                                "<collision><geometry><box size='99 99'/></geometry></collision>",
                                "<visual><geometry><cylinder radius='abc' length='1'/></geometry></visual>",
                                "<visual><geometry><mesh filename='meshes/base.obj' scale='nan 1 1'/></geometry></visual>",
                                "<visual><geometry></geometry></visual>", "<visual><origin xyz='1e300 0 0'/>"};
    std::string text = mutated(seed, rng);
    for (int i = static_cast<int>(rng() % 3); i > 0; --i)
      text.insert(rng() % (text.size() + 1), xml[rng() % (sizeof xml / sizeof *xml)]);
    // the meshes' paths made absolute after the mutation: the inputs do not depend on where
    // the repository lies
    const std::string meshes = kSrc + "/sim/robots/ur5e/meshes/";
    for (std::size_t p = 0; (p = text.find("\"meshes/", p)) != std::string::npos; p += meshes.size() + 1)
      text.replace(p + 1, 7, meshes);
    std::ofstream(file, std::ios::binary) << text;
    try {
      const auto model = std::make_shared<sim::RobotModel>(sim::load_robot_model(file, "camera_optical"));
      const sim::ArmKinematics kin(*model);
      const Eigen::VectorXd q = 0.5 * (kin.lower() + kin.upper());
      kin.inverse(kin.base_T_camera(q), q);
      sim::ArmRobot arm(model, Eigen::Isometry3d::Identity(), empty, {}, {}, q);
      sim::Vector6d v;
      for (int i = 0; i < 6; ++i) v[i] = uniform_extreme(rng);
      if (v.allFinite()) arm.move(v, 0.01, sim::Workspace{});
      if (!arm.world_T_camera().matrix().allFinite()) std::abort();  // a NaN pose must never come out
    } catch (const std::exception&) {
    }
  }
};

// campaign merge (issue 18, item 17): two real shards, the second's campaign.json or
// campaign.csv mutated; the merge refuses it in one line or merges it, never anything else.
struct CampaignTarget : Target {
  std::filesystem::path dir = std::filesystem::temp_directory_path() / ("fuzz_campaign_" + std::to_string(getpid()));
  std::string json, csv;
  CampaignTarget() {
    const auto cell = sim::build_cell(sim::load_scenario(kSrc + "/sim/scenarios/fig5.yaml"));
    for (int shard = 1; shard <= 2; ++shard) {
      experiment::CampaignOptions o;
      o.runs = 3;
      o.models = {control::InteractionModel::kCurrent};
      o.base = experiment::servo_config_for(*cell);
      o.source = loop::FeatureSource::kIdeal;
      o.max_iterations = 5;
      o.threads = 1;
      o.shard_index = shard;
      o.shard_count = 2;
      o.out_dir = dir / std::to_string(shard);
      experiment::run_campaign(*cell, o);
    }
    json = read((dir / "2" / "campaign.json").string());
    csv = read((dir / "2" / "campaign.csv").string());
  }
  ~CampaignTarget() override { std::filesystem::remove_all(dir); }
  void one(std::mt19937_64& rng) override {
    const bool mutate_json = rng() % 2;
    std::ofstream(dir / "2" / "campaign.json", std::ios::binary) << (mutate_json ? mutated(json, rng) : json);
    std::ofstream(dir / "2" / "campaign.csv", std::ios::binary) << (mutate_json ? csv : mutated(csv, rng));
    try {
      experiment::merge_campaigns({dir / "1", dir / "2"}, dir / "merged");
    } catch (const std::invalid_argument& e) {
      if (std::strchr(e.what(), '\n')) std::abort();  // one line
    }
  }
};

struct MeshTarget : Target {
  std::string obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 2 4 3\n";
  std::string ply = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                    "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
  std::filesystem::path dir = std::filesystem::temp_directory_path();
  void one(std::mt19937_64& rng) override {
    const bool use_ply = rng() % 2;
    const auto file = dir / ("fuzz_mesh_" + std::to_string(getpid()) + (use_ply ? ".ply" : ".obj"));
    std::ofstream(file, std::ios::binary) << mutated(use_ply ? ply : obj, rng);
    try {
      sim::load_mesh(file);  // walked by check_mesh_file first, then assimp
    } catch (const std::exception&) {
    }
    std::filesystem::remove(file);
  }
};

struct DecoderTarget : Target {
  std::unique_ptr<sim::Cell> cell = sim::build_cell(sim::load_scenario(kSrc + "/sim/scenarios/plane.yaml"));
  cv::Mat image = sim::render_image(*cell, cell->scenario.world_T_initial(), 1);
  vision::SpotDecoder decoder{pattern::WindowTable(cell->projector->pattern(), {3, 3})};
  // issue 19: the distance-3 pattern, cast and decoded with correction, every other input
  std::unique_ptr<sim::Cell> cell_d3 = [] {
    sim::Scenario s = sim::load_scenario(kSrc + "/sim/scenarios/plane.yaml");
    s.projector.pattern = kSrc + "/servo/pattern/data/marray_20x20_k3_w3_d3.txt";
    return sim::build_cell(sim::resolve(s));
  }();
  cv::Mat image_d3 = sim::render_image(*cell_d3, cell_d3->scenario.world_T_initial(), 1);
  vision::SpotDecoder decoder_d3{pattern::WindowTable(cell_d3->projector->pattern(), {3, 3})};
  void one(std::mt19937_64& rng) override {
    const bool d3 = rng() % 2;
    cv::Mat img = (d3 ? image_d3 : image).clone();
    // smear, blank, saturate and noise random patches: spots merge, vanish, change colour
    const int patches = 1 + static_cast<int>(rng() % 20);
    for (int i = 0; i < patches; ++i) {
      const int x = static_cast<int>(rng() % img.cols), y = static_cast<int>(rng() % img.rows);
      const int w = 1 + static_cast<int>(rng() % 120), h = 1 + static_cast<int>(rng() % 120);
      const cv::Rect r = cv::Rect(x, y, w, h) & cv::Rect(0, 0, img.cols, img.rows);
      cv::Mat roi = img(r);
      switch (rng() % 4) {
        case 0: roi.setTo(cv::Scalar(rng() % 256, rng() % 256, rng() % 256)); break;
        case 1: cv::randu(roi, 0, 256); break;
        case 2: roi += cv::Scalar(rng() % 128, rng() % 128, rng() % 128); break;
        default: cv::flip(roi.clone(), roi, 1);
      }
    }
    // and sometimes an odd size
    if (rng() % 8 == 0) img = img(cv::Rect(0, 0, 1 + static_cast<int>(rng() % img.cols), 1 + static_cast<int>(rng() % img.rows))).clone();
    // half the time with the frame's epipolar geometry, from a pose nudged off the true one
    // (or a wild one): the calibrated steps see the same images
    std::optional<vision::EpipolarGeometry> geometry;
    if (rng() % 2) {
      Eigen::Isometry3d wTc = cell->scenario.world_T_initial();
      const double scale = rng() % 10 == 0 ? 1e3 : 0.02;
      std::uniform_real_distribution<double> u(-1, 1);
      wTc.translation() += scale * Eigen::Vector3d(u(rng), u(rng), u(rng));
      geometry.emplace(experiment::camera_intrinsics_of(*cell), experiment::projector_model_of(*cell), wTc,
                       0.5 + static_cast<double>(rng() % 100) / 10.0);
    }
    try {
      (d3 ? decoder_d3 : decoder).decode(img, geometry ? &*geometry : nullptr);
    } catch (const std::exception&) {
    }
  }
};

// The servo service's handlers with what a rogue DDS participant can send.
struct ServoTarget : Target {
  std::unique_ptr<sim::Cell> cell = sim::build_cell(sim::load_scenario(kSrc + "/sim/scenarios/plane.yaml"));
  cv::Mat image = sim::render_image(*cell, cell->scenario.world_T_desired, 1);
  servo::ServoStateMachine machine{
      std::make_unique<servo::ServoPipeline>(pattern::WindowTable(cell->projector->pattern(), {3, 3}), servo::ServoConfig{}),
      servo::ServoTiming{}};
  double now = 0;
  void one(std::mt19937_64& rng) override {
    now += 0.01;
    const servo::Stamp stamp{static_cast<std::int32_t>(rng() % 4), static_cast<std::uint32_t>(rng() % 3 * 40000000)};
    switch (rng() % 6) {
      case 0: machine.on_command(static_cast<int>(rng() % 8)); break;
      case 1: {
        servo::CameraInfoMsg c;
        c.width = rng() % 2 ? 640 : static_cast<std::uint32_t>(rng());
        c.height = rng() % 2 ? 480 : static_cast<std::uint32_t>(rng());
        c.k = {800, 0, 319.5, 0, 800, 239.5, 0, 0, 1};
        for (auto& v : c.k)
          if (rng() % 4 == 0) v = uniform_extreme(rng);
        if (rng() % 3 == 0) c.k.resize(rng() % 12);
        c.d.resize(rng() % 20);
        for (auto& v : c.d) v = uniform_extreme(rng);
        machine.on_camera_info(c);
        break;
      }
      case 2: machine.on_sim_status({stamp, rng() % 2 == 0, rng() % 4 == 0}); break;
      case 3: {
        Eigen::Isometry3d T = cell->scenario.world_T_desired;
        if (rng() % 3 == 0) T.translation().x() = uniform_extreme(rng);
        machine.on_pose(stamp, T);
        break;
      }
      case 4: machine.tick(now); break;
      default: {
        std::string enc = rng() % 4 ? "rgb8" : mutated("rgb8", rng);
        servo::ImageView v{stamp, enc, static_cast<std::uint32_t>(image.cols), static_cast<std::uint32_t>(image.rows),
                           static_cast<std::uint32_t>(image.cols * 3), 0, image.data, image.total() * 3};
        if (rng() % 3 == 0) v.width = static_cast<std::uint32_t>(rng());
        if (rng() % 3 == 0) v.height = static_cast<std::uint32_t>(rng() % 5000);
        if (rng() % 3 == 0) v.step = v.width * 3;  // wraps for huge widths
        if (rng() % 3 == 0) v.size = rng() % (v.size + 1);
        if (rng() % 2) {
          machine.on_image(v, now);
          break;
        }
        // with a white reference frame (servo run --white-frame): the same bytes, its header
        // mutated apart, at its own stamp now and then
        servo::ImageView white = v;
        if (rng() % 4 == 0) white.stamp.nanosec = static_cast<std::uint32_t>(rng());
        if (rng() % 3 == 0) white.width = static_cast<std::uint32_t>(rng() % 5000);
        if (rng() % 3 == 0) white.size = rng() % (image.total() * 3 + 1);
        machine.on_image(v, now, &white);
      }
    }
  }
};

// The sim service's handlers with what a rogue DDS participant can send.
struct CellTarget : Target {
  sim::Scenario scenario = sim::load_scenario(kSrc + "/sim/scenarios/plane.yaml");
  sim::CellStateMachine lockstep{scenario, {}};
  sim::CellStateMachine realtime{scenario, [] {
                                   sim::CellOptions p;
                                   p.timing = sim::Timing::kRealtime;
                                   return p;
                                 }()};
  double now = 0;
  void one(std::mt19937_64& rng) override {
    now += 0.002;
    for (sim::CellStateMachine* m : {&lockstep, &realtime}) {
      switch (rng() % 4) {
        case 0: {
          static const char* args[] = {"", "initial", "desired", "1e300 0 0 0 0 0", "1 2 3 4 5 6", "nan 0 0 0 0 0",
                                       "/nonexistent.yaml", "\xff\x01"};
          const int c = static_cast<int>(rng() % 8);
          const std::string arg = c == 0 ? "/nonexistent.yaml" : args[rng() % 8];
          m->on_command({c, arg, rng() % 2 ? rng() : rng() % 10}, now);
          break;
        }
        case 1: {
          sim::TwistMsg t;
          t.stamp_sec = rng() % 4 ? static_cast<std::int64_t>(now) : static_cast<std::int64_t>(rng());
          t.stamp_nanosec = static_cast<std::uint32_t>(rng() % 2 ? rng() : rng() % 1000000000);
          t.frame_id = rng() % 4 ? "camera_optical" : mutated("camera_optical", rng);
          for (int i = 0; i < 6; ++i) t.twist[i] = uniform_extreme(rng);
          m->on_twist(t, now);
          break;
        }
        case 2: {
          sim::ServoReport r;
          r.stamp_sec = static_cast<std::int64_t>(rng() % 3);
          r.stamp_nanosec = static_cast<std::uint32_t>(rng());
          r.state = static_cast<std::uint8_t>(rng() % 8);
          m->on_servo_status(r, now);
          break;
        }
        default: {
          sim::CellOutput o = m->poll(now);
          if (o.load) m->load_failed("fuzz: not loaded");
        }
      }
    }
    if (!scenario.workspace.contains(lockstep.world_T_camera().translation()) ||
        !scenario.workspace.contains(realtime.world_T_camera().translation())) {
      std::fprintf(stderr, "fuzz cell: the camera left the workspace\n");
      std::abort();
    }
  }
};

// The bytes a rogue participant puts on the wire: every topic type's CDR, mutated, through the
// generated deserialisers the readers use (lengths beyond the payload must be refused, not
// allocated), then the checks the services apply to what decodes.
struct CdrTarget : Target {
  template <typename PubSubType>
  struct Type {
    typename PubSubType::type sample;
    std::string bytes;
  };
  template <typename PubSubType>
  static std::string serialized(typename PubSubType::type& sample) {
    PubSubType t;
    eprosima::fastrtps::rtps::SerializedPayload_t p(t.getSerializedSizeProvider(&sample)());
    t.serialize(&sample, &p);
    return std::string(reinterpret_cast<const char*>(p.data), p.length);
  }
  template <typename PubSubType>
  static bool decode(const std::string& bytes, typename PubSubType::type& out) {
    PubSubType t;
    eprosima::fastrtps::rtps::SerializedPayload_t p(static_cast<std::uint32_t>(bytes.size()) + 4);
    std::memcpy(p.data, bytes.data(), bytes.size());
    p.length = static_cast<std::uint32_t>(bytes.size());
    try {
      return t.deserialize(&p, &out);
    } catch (const std::exception&) {
      return false;
    }
  }
  std::vector<std::string> seeds;
  CdrTarget() {
    sensor_msgs::msg::dds_::Image_ img;
    img.encoding("rgb8");
    img.width(4);
    img.height(2);
    img.step(12);
    img.data().assign(24, 7);
    seeds.push_back(serialized<sensor_msgs::msg::dds_::Image_PubSubType>(img));
    sensor_msgs::msg::dds_::CameraInfo_ ci;
    ci.width(640);
    ci.height(480);
    ci.d({0.1, 0.2, 0, 0, 0});
    seeds.push_back(serialized<sensor_msgs::msg::dds_::CameraInfo_PubSubType>(ci));
    geometry_msgs::msg::dds_::TwistStamped_ tw;
    tw.header().frame_id("camera_optical");
    seeds.push_back(serialized<geometry_msgs::msg::dds_::TwistStamped_PubSubType>(tw));
    cell_msgs::msg::dds_::SimControl_ c;
    c.argument("initial");
    seeds.push_back(serialized<cell_msgs::msg::dds_::SimControl_PubSubType>(c));
    cell_msgs::msg::dds_::DecodedSpots_ ds;
    ds.spots().resize(3);
    seeds.push_back(serialized<cell_msgs::msg::dds_::DecodedSpots_PubSubType>(ds));
    cell_msgs::msg::dds_::SpotTruthArray_ st;
    st.spots().resize(3);
    seeds.push_back(serialized<cell_msgs::msg::dds_::SpotTruthArray_PubSubType>(st));
    cell_msgs::msg::dds_::ServoStatus_ ss;
    ss.reason("taught 388 features");
    seeds.push_back(serialized<cell_msgs::msg::dds_::ServoStatus_PubSubType>(ss));
  }
  void one(std::mt19937_64& rng) override {
    const std::size_t which = rng() % seeds.size();
    const std::string bytes = mutated(seeds[which], rng);
    switch (which) {
      case 0: {
        sensor_msgs::msg::dds_::Image_ m;
        if (decode<sensor_msgs::msg::dds_::Image_PubSubType>(bytes, m))
          servo::ServoStateMachine::reject_reason({{m.header().stamp().sec(), m.header().stamp().nanosec()}, m.encoding(),
                                                   m.width(), m.height(), m.step(), m.is_bigendian(), m.data().data(),
                                                   m.data().size()},
                                                  servo::CameraInfoMsg{m.width(), m.height(), {}, {}});
        break;
      }
      case 1: {
        sensor_msgs::msg::dds_::CameraInfo_ m;
        if (decode<sensor_msgs::msg::dds_::CameraInfo_PubSubType>(bytes, m))
          servo::ServoStateMachine::camera_info_problem({m.width(), m.height(), {m.k().begin(), m.k().end()}, m.d()});
        break;
      }
      case 2: {
        geometry_msgs::msg::dds_::TwistStamped_ m;
        decode<geometry_msgs::msg::dds_::TwistStamped_PubSubType>(bytes, m);
        break;
      }
      case 3: {
        cell_msgs::msg::dds_::SimControl_ m;
        decode<cell_msgs::msg::dds_::SimControl_PubSubType>(bytes, m);
        break;
      }
      case 4: {
        cell_msgs::msg::dds_::DecodedSpots_ m;
        decode<cell_msgs::msg::dds_::DecodedSpots_PubSubType>(bytes, m);
        break;
      }
      case 5: {
        cell_msgs::msg::dds_::SpotTruthArray_ m;
        decode<cell_msgs::msg::dds_::SpotTruthArray_PubSubType>(bytes, m);
        break;
      }
      default: {
        cell_msgs::msg::dds_::ServoStatus_ m;
        decode<cell_msgs::msg::dds_::ServoStatus_PubSubType>(bytes, m);
      }
    }
  }
};

}  // namespace

// A recording (issue 21): framing, chunks, CRCs, schemas and channels, and each message
// decoded as its topic's type, as servo replay decodes it.
// What a live viewer sends `cellsim bridge`: its opening request and its frames (foxglove/
// websocket.hpp), mutated, fed in random pieces; a frame reader never holds more than a frame.
struct WebsocketTarget : Target {
  std::string request = "GET / HTTP/1.1\r\nHost: localhost\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
                        "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n"
                        "Sec-WebSocket-Protocol: foxglove.websocket.v1\r\n\r\n";
  std::string frames = [] {
    std::string f;
    for (const std::string& p : {std::string("{\"op\":\"subscribe\",\"subscriptions\":[{\"id\":1,\"channelId\":1}]}"),
                                 std::string(300, 'x'), std::string("ping")}) {
      f.push_back(static_cast<char>(0x81));
      f.push_back(static_cast<char>(0x80 | (p.size() < 126 ? p.size() : 126)));
      if (p.size() >= 126) f.append({static_cast<char>(p.size() >> 8), static_cast<char>(p.size() & 0xFF)});
      f.append("\x01\x02\x03\x04", 4);
      for (std::size_t i = 0; i < p.size(); ++i) f.push_back(static_cast<char>(p[i] ^ (1 + i % 4)));
    }
    return f;
  }();
  void one(std::mt19937_64& rng) override {
    const foxglove::Handshake h = foxglove::parse_handshake(mutated(request, rng));
    if (h.error.empty()) foxglove::handshake_reply(h.key);
    const std::string bytes = mutated(frames, rng);
    foxglove::FrameReader reader;
    std::vector<foxglove::Frame> out;
    for (std::size_t at = 0; at < bytes.size();) {
      const std::size_t n = std::min<std::size_t>(bytes.size() - at, 1 + rng() % 64);
      if (!reader.feed(bytes.data() + at, n, out)) break;
      at += n;
    }
  }
};

struct McapTarget : Target {
  std::string seed;
  McapTarget() {
    const auto file = std::filesystem::temp_directory_path() / ("fuzz_mcap_" + std::to_string(getpid()) + ".mcap");
    {
      mcap::WriterOptions o;
      o.chunk_bytes = 96;  // several chunks in a small file
      mcap::Writer w(file, o);
      const auto si = w.add_schema("sensor_msgs/msg/Image", "ros2msg", "std_msgs/Header header\nuint32 height\n");
      const auto st = w.add_schema("geometry_msgs/msg/TwistStamped", "ros2msg", "std_msgs/Header header\n");
      const auto ci = w.add_channel(si, "/camera/image_raw", "cdr", {{"offered_qos_profiles", "- history: keep_last"}});
      const auto ct = w.add_channel(st, "/servo/cmd_twist", "cdr", {});
      w.add_metadata("cellsim", {{"scenario", "plane"}});
      sensor_msgs::msg::dds_::Image_ img;
      img.encoding("rgb8");
      img.width(2);
      img.height(1);
      img.step(6);
      img.data().assign(6, 9);
      geometry_msgs::msg::dds_::TwistStamped_ tw;
      tw.twist().linear().x(0.01);
      for (std::uint32_t k = 0; k < 3; ++k) {
        const std::string a = CdrTarget::serialized<sensor_msgs::msg::dds_::Image_PubSubType>(img);
        const std::string b = CdrTarget::serialized<geometry_msgs::msg::dds_::TwistStamped_PubSubType>(tw);
        w.write_message(ci, k, 10 + k, 9 + k, reinterpret_cast<const std::uint8_t*>(a.data()), a.size());
        w.write_message(ct, k, 11 + k, 10 + k, reinterpret_cast<const std::uint8_t*>(b.data()), b.size());
      }
    }
    seed = read(file.string());
    std::filesystem::remove(file);
    unchecked = without_crcs(seed);
  }
  // the same file with its chunk CRCs off (0), so that mutations get past them into the records
  static std::string without_crcs(std::string file) {
    for (std::size_t at = 8; at + 9 <= file.size();) {
      std::uint64_t len = 0;
      for (int i = 0; i < 8; ++i) len |= static_cast<std::uint64_t>(static_cast<unsigned char>(file[at + 1 + i])) << (8 * i);
      if (static_cast<unsigned char>(file[at]) == mcap::kChunk) file.replace(at + 9 + 24, 4, 4, '\0');
      if (len > file.size()) break;
      at += 9 + len;
    }
    return file;
  }
  std::string unchecked;
  void one(std::mt19937_64& rng) override {
    try {
      mcap::read_mcap(mutated(rng() % 2 ? seed : unchecked, rng), "fuzz.mcap", [](const mcap::Channel& c, const mcap::MessageView& m) {
        const std::string bytes(reinterpret_cast<const char*>(m.data), m.size);
        if (c.topic == "/camera/image_raw") {
          sensor_msgs::msg::dds_::Image_ img;
          CdrTarget::decode<sensor_msgs::msg::dds_::Image_PubSubType>(bytes, img);
        } else {
          geometry_msgs::msg::dds_::TwistStamped_ t;
          CdrTarget::decode<geometry_msgs::msg::dds_::TwistStamped_PubSubType>(bytes, t);
        }
      });
    } catch (const mcap::FormatError&) {
    }
  }
};

// A recording through `servo replay` (issue 40, item 10): a small cell's camera_info, a TEACH,
// frames of status, pose, image and twist, mutated and replayed through the servo's state
// machine from a file, as a user replays one: every record decoded as its topic's type.
struct ReplayTarget : Target {
  std::string seed;
  std::filesystem::path file = std::filesystem::temp_directory_path() / ("fuzz_replay_" + std::to_string(getpid()) + ".mcap");
  template <typename PubSubType>
  static void put(mcap::Writer& w, std::uint16_t channel, std::uint32_t k, typename PubSubType::type& m) {
    const std::string b = CdrTarget::serialized<PubSubType>(m);
    w.write_message(channel, k, 100 + k, 100 + k, reinterpret_cast<const std::uint8_t*>(b.data()), b.size());
  }
  ReplayTarget() {
    std::filesystem::remove(file);
    {
      mcap::WriterOptions o;
      o.chunk_bytes = 2048;
      mcap::Writer w(file, o);
      const auto sc = w.add_schema("x", "ros2msg", "");
      const auto info = w.add_channel(sc, "/camera/camera_info", "cdr", {});
      const auto control = w.add_channel(sc, "/sim/control", "cdr", {});
      const auto status = w.add_channel(sc, "/sim/status", "cdr", {});
      const auto pose = w.add_channel(sc, "/sim/camera_pose", "cdr", {});
      const auto image = w.add_channel(sc, "/camera/image_raw", "cdr", {});
      const auto white = w.add_channel(sc, "/camera/white/image_raw", "cdr", {});
      const auto twist = w.add_channel(sc, "/servo/cmd_twist", "cdr", {});
      sensor_msgs::msg::dds_::CameraInfo_ ci;
      ci.width(64);
      ci.height(48);
      ci.k({80, 0, 31.5, 0, 80, 23.5, 0, 0, 1});
      put<sensor_msgs::msg::dds_::CameraInfo_PubSubType>(w, info, 0, ci);
      cell_msgs::msg::dds_::SimControl_ teach;
      teach.command(2);  // TEACH
      put<cell_msgs::msg::dds_::SimControl_PubSubType>(w, control, 0, teach);
      std::mt19937_64 rng(7);
      for (std::uint32_t k = 0; k < 3; ++k) {
        const auto stamp = cell_dds::stamp_of(k, 0.04);
        cell_msgs::msg::dds_::SimStatus_ st;
        st.header().stamp(stamp);
        st.state(k == 0 ? 3 : 1);  // TEACHING, then RUNNING
        put<cell_msgs::msg::dds_::SimStatus_PubSubType>(w, status, k, st);
        geometry_msgs::msg::dds_::PoseStamped_ p;
        p.header().stamp(stamp);
        p.pose().orientation().w(1);
        put<geometry_msgs::msg::dds_::PoseStamped_PubSubType>(w, pose, k, p);
        sensor_msgs::msg::dds_::Image_ img;
        img.header().stamp(stamp);
        img.encoding("rgb8");
        img.width(64);
        img.height(48);
        img.step(192);
        img.data().resize(64 * 48 * 3);
        for (auto& b : img.data()) b = static_cast<std::uint8_t>(rng() % 4 == 0 ? 255 : 0);
        put<sensor_msgs::msg::dds_::Image_PubSubType>(w, image, k, img);
        std::fill(img.data().begin(), img.data().end(), std::uint8_t{200});  // its white frame
        put<sensor_msgs::msg::dds_::Image_PubSubType>(w, white, k, img);
        geometry_msgs::msg::dds_::TwistStamped_ t;
        t.header().stamp(stamp);
        put<geometry_msgs::msg::dds_::TwistStamped_PubSubType>(w, twist, k, t);
      }
    }
    seed = McapTarget::without_crcs(read(file.string()));
  }
  ~ReplayTarget() override { std::filesystem::remove(file); }
  void one(std::mt19937_64& rng) override {
    std::filesystem::remove(file);
    // half of the inputs keep every record's length (bytes changed in place), so that they
    // reach the messages, their decoding and the servo; the rest are cut, grown and spliced
    std::string input = seed;
    if (rng() % 2) {
      for (int n = 1 + static_cast<int>(rng() % 4); n > 0; --n)
        input[rng() % input.size()] = static_cast<char>(rng() % 3 ? rng() : (rng() % 2 ? 0 : 0xff));
    } else {
      input = mutated(seed, rng);
    }
    std::ofstream(file, std::ios::binary) << input;
    servo::ReplayOptions o;
    o.recording = file;
    o.pattern = kSrc + "/servo/pattern/data/marray_20x20_k3_w3.txt";
    o.plot = false;
    o.config.white_frame = rng() % 2;  // the white frames paired with their images, or left aside
    try {
      servo::run_replay(o);
    } catch (const std::exception& e) {
      if (std::getenv("FUZZ_VERBOSE")) std::fprintf(stderr, "%s\n", e.what());
    }
  }
};

int main(int argc, char** argv) {
  std::string target;
  long iterations = 1000;
  double seconds = 0;
  std::uint64_t seed = 1;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string k = argv[i], v = argv[i + 1];
    if (k == "--target") target = v;
    else if (k == "--iterations") iterations = std::stol(v);
    else if (k == "--seconds") seconds = std::stod(v);
    else if (k == "--seed") seed = std::stoull(v);
    else {
      std::fprintf(stderr, "fuzz_targets: unknown option %s\n", k.c_str());
      return 2;
    }
  }
  std::unique_ptr<Target> t;
  if (target == "pattern") t = std::make_unique<PatternTarget>();
  else if (target == "scenario") t = std::make_unique<ScenarioTarget>();
  else if (target == "mesh") t = std::make_unique<MeshTarget>();
  else if (target == "urdf") t = std::make_unique<UrdfTarget>();
  else if (target == "decoder") t = std::make_unique<DecoderTarget>();
  else if (target == "servo") t = std::make_unique<ServoTarget>();
  else if (target == "cell") t = std::make_unique<CellTarget>();
  else if (target == "cdr") t = std::make_unique<CdrTarget>();
  else if (target == "campaign") t = std::make_unique<CampaignTarget>();
  else if (target == "mcap") t = std::make_unique<McapTarget>();
  else if (target == "replay") t = std::make_unique<ReplayTarget>();
  else if (target == "websocket") t = std::make_unique<WebsocketTarget>();
  else {
    std::fprintf(stderr, "fuzz_targets: --target decoder|pattern|scenario|mesh|urdf|cell|servo|cdr|campaign|mcap|replay|websocket\n");
    return 2;
  }
  std::mt19937_64 rng(seed);
  const auto t0 = std::chrono::steady_clock::now();
  long n = 0;
  for (; seconds > 0 ? std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() < seconds : n < iterations;
       ++n)
    t->one(rng);
  const double took = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::printf("fuzz %s: %ld inputs in %.1f s (seed %llu), no crash\n", target.c_str(), n, took,
              static_cast<unsigned long long>(seed));
  return 0;
}
