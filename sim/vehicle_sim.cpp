#include "sim/vehicle_sim.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <stdexcept>
#include <string>

#include "vehicle_models/mjcf_builder.hpp"
#include "vehicle_models/steering.hpp"

namespace conesim::sim {

namespace {

constexpr double kGravity = 9.81;
// brake balance: share of the braking torque on each front wheel (the rear gets the rest)
constexpr double kFrontBrakeShare = 0.3;
// slip band over which traction control and ABS fade the torque out
constexpr double kSlipFadeBand = 0.10;

int require_id(const mjModel* m, int type, const std::string& name) {
  const int id = mj_name2id(m, type, name.c_str());
  if (id < 0) throw std::runtime_error("MuJoCo model has no " + name);
  return id;
}

// torque factor of traction control / ABS for a slip ratio beyond the target
double slip_fade(double slip, double target) {
  return std::clamp(1.0 - (slip - target) / kSlipFadeBand, 0.0, 1.0);
}

}  // namespace

mjModel* load_mjcf_model(const std::string& xml) {
  auto vfs = std::make_unique<mjVFS>();
  mj_defaultVFS(vfs.get());
  const char* name = "conesim_car.xml";
  if (mj_makeEmptyFileVFS(vfs.get(), name, static_cast<int>(xml.size())) != 0)
    throw std::runtime_error("MuJoCo: cannot create the in-memory model file");
  std::memcpy(vfs->filedata[mj_findFileVFS(vfs.get(), name)], xml.data(), xml.size());
  char error[1000] = "";
  mjModel* model = mj_loadXML(name, vfs.get(), error, sizeof(error));
  mj_deleteVFS(vfs.get());
  if (!model) throw std::runtime_error(std::string("MuJoCo could not load the car: ") + error);
  return model;
}

VehicleSim::VehicleSim(const vehicle_models::VehicleParams& params, const core::Pose2& start,
                       const tracks::GroundModel& ground)
    : params_(params), ground_(ground) {
  if (const std::string error = params.validate(); !error.empty())
    throw std::invalid_argument("vehicle parameters: " + error);

  // the ground: the plane, or a height field over the ground model's grid, its heights scaled
  // into 0..1 of their range
  vehicle_models::MjcfOptions options;
  const tracks::GroundGrid& grid = ground.grid();
  const double elevation_m = std::max(grid.max_z - grid.min_z, 1e-3);
  if (!ground.flat()) {
    auto& h = options.ground;
    h.nrow = grid.ny;
    h.ncol = grid.nx;
    h.half_x_m = 0.5 * (grid.nx - 1) * grid.cell_m;
    h.half_y_m = 0.5 * (grid.ny - 1) * grid.cell_m;
    h.centre_x_m = grid.x0 + h.half_x_m;
    h.centre_y_m = grid.y0 + h.half_y_m;
    h.elevation_m = elevation_m;
    h.base_z_m = grid.min_z;
  }
  model_ = load_mjcf_model(vehicle_models::build_mjcf(params, options));
  if (!ground.flat()) {
    const int field = require_id(model_, mjOBJ_HFIELD, "ground");
    float* heights = model_->hfield_data + model_->hfield_adr[field];
    for (size_t k = 0; k < grid.z.size(); ++k)
      heights[k] = static_cast<float>((grid.z[k] - grid.min_z) / elevation_m);
  }
  data_ = mj_makeData(model_);

  // look up what the controller drives and reads
  chassis_body_ = require_id(model_, mjOBJ_BODY, vehicle_models::MjcfNames::kChassis);
  for (int c = 0; c < 4; ++c) {
    const std::string corner = vehicle_models::MjcfNames::kCorners[c];
    knuckle_body_[c] = require_id(model_, mjOBJ_BODY, "knuckle_" + corner);
    const int spin = require_id(model_, mjOBJ_JOINT, "spin_" + corner);
    spin_qvel_[c] = model_->jnt_dofadr[spin];
    spin_qpos_[c] = model_->jnt_qposadr[spin];
    drive_actuator_[c] = require_id(model_, mjOBJ_ACTUATOR, "drive_" + corner);
    if (c < 2) {
      steer_qpos_[c] = model_->jnt_qposadr[require_id(model_, mjOBJ_JOINT, "steer_" + corner)];
      steer_actuator_[c] = require_id(model_, mjOBJ_ACTUATOR, "steer_" + corner);
    }
  }

  // the IMU's sensors
  gyro_adr_ = model_->sensor_adr[require_id(model_, mjOBJ_SENSOR, "gyro")];
  accel_adr_ = model_->sensor_adr[require_id(model_, mjOBJ_SENSOR, "accelerometer")];

  // place the car: the free joint's position and yaw quaternion
  const int free_joint = require_id(model_, mjOBJ_JOINT, vehicle_models::MjcfNames::kChassis);
  mjtNum* q = data_->qpos + model_->jnt_qposadr[free_joint];
  q[0] = start.x;
  q[1] = start.y;
  if (!ground.flat()) {
    // level, the wheel over the highest ground touching it (the others settle onto theirs)
    double lift = -1e9;
    for (double ax : {0.0, params.wheelbase_m})
      for (double ay : {-0.5 * params.track_m, 0.5 * params.track_m}) {
        const Eigen::Vector2d w = start.transform(Eigen::Vector2d(ax, ay));
        lift = std::max(lift, ground.height(w.x(), w.y()));
      }
    q[2] += lift;
  }
  q[3] = std::cos(0.5 * start.yaw);
  q[4] = 0.0;
  q[5] = 0.0;
  q[6] = std::sin(0.5 * start.yaw);
  mj_forward(model_, data_);
}

VehicleSim::~VehicleSim() {
  mj_deleteData(data_);
  mj_deleteModel(model_);
}

double VehicleSim::timestep_s() const { return model_->opt.timestep; }

void VehicleSim::step(const core::VehicleCommand& command, bool imu) {
  // the sensors (IMU, encoders) are outputs only: skipping them leaves the motion unchanged
  if (imu)
    model_->opt.disableflags &= ~mjDSBL_SENSOR;
  else
    model_->opt.disableflags |= mjDSBL_SENSOR;
  imu_fresh_ = imu;
  mj_step1(model_, data_);
  apply_controls(command);
  mj_step2(model_, data_);
}

void VehicleSim::apply_controls(const core::VehicleCommand& command) {
  const auto& p = params_;
  const double dt = model_->opt.timestep;

  // steering: rate-limited single-track angle, split into the two wheel angles
  const double target = std::clamp(command.steer_rad, -p.max_steer_rad, p.max_steer_rad);
  const double max_change = p.max_steer_rate_rps * dt;
  steer_rad_ += std::clamp(target - steer_rad_, -max_change, max_change);
  const auto wheels = vehicle_models::split_steering(steer_rad_, p);
  data_->ctrl[steer_actuator_[0]] = wheels.left_rad;
  data_->ctrl[steer_actuator_[1]] = wheels.right_rad;

  // chassis speed and the resistances the drive has to make up for
  mjtNum vel[6];
  mj_objectVelocity(model_, data_, mjOBJ_BODY, chassis_body_, vel, 1);
  const double vx = vel[3];
  const double vy = vel[4];
  const double speed = std::hypot(vx, vy);
  const double q_dyn = 0.5 * p.air_density_kgm3 * speed * speed;
  const double drag_n = q_dyn * p.drag_area_m2;
  const double downforce_n = q_dyn * p.lift_area_m2;
  const double rolling_n =
      speed > 0.05 ? p.rolling_resistance * (p.mass_kg * kGravity + downforce_n) : 0.0;

  // aero drag, downforce and rolling resistance act on the chassis at its centre of mass
  mjtNum* xfrc = data_->xfrc_applied + 6 * chassis_body_;
  std::fill(xfrc, xfrc + 6, 0.0);
  if (speed > 1e-3) {
    const mjtNum* R = data_->xmat + 9 * chassis_body_;
    // velocity direction in the world frame
    const double wx = (R[0] * vx + R[1] * vy) / speed;
    const double wy = (R[3] * vx + R[4] * vy) / speed;
    xfrc[0] = -(drag_n + rolling_n) * wx;
    xfrc[1] = -(drag_n + rolling_n) * wy;
    xfrc[2] = -downforce_n;
  }

  // longitudinal force wanted at the tyres, resistances included
  double force_n = p.mass_kg * command.accel_mps2 + drag_n + rolling_n;
  if (command.hold_stopped) force_n = -p.mass_kg * 2.0 * kGravity;

  for (int c = 0; c < 4; ++c) {
    const bool front = c < 2;
    const double omega = data_->qvel[spin_qvel_[c]];
    // wheel centre speed along the wheel's heading (the knuckle does not spin)
    mjtNum kv[6];
    mj_objectVelocity(model_, data_, mjOBJ_BODY, knuckle_body_[c], kv, 1);
    const double v_wheel = kv[3];
    const double slip = (omega * p.wheel_radius_m - v_wheel) / std::max(std::abs(v_wheel), 1.0);

    double torque = 0.0;
    if (force_n >= 0.0) {
      // drive: split by the axles' torque limits, then power limit and traction control
      const double axle_max = front ? p.max_torque_front_nm : p.max_torque_rear_nm;
      const double total_max = 2.0 * (p.max_torque_front_nm + p.max_torque_rear_nm);
      torque = std::min(force_n * p.wheel_radius_m * axle_max / total_max, axle_max);
      const double power_per_motor = p.max_power_w / 4.0;
      if (std::abs(omega) > 1e-3) torque = std::min(torque, power_per_motor / std::abs(omega));
      torque *= slip_fade(slip, p.slip_target);
    } else {
      // brake: fixed balance, ABS on the slip, torque against the spin (smooth at standstill)
      const double share = front ? kFrontBrakeShare : 0.5 - kFrontBrakeShare;
      double brake = std::min(-force_n * p.wheel_radius_m * share, p.max_brake_torque_nm);
      brake *= slip_fade(-slip, p.slip_target);
      torque = -brake * std::clamp(omega / 2.0, -1.0, 1.0);
    }
    data_->ctrl[drive_actuator_[c]] = torque;
  }
}

void VehicleSim::require_imu() const {
  if (!imu_fresh_)
    throw std::logic_error("VehicleSim: IMU read after a step that skipped the sensors");
}

Eigen::Vector3d VehicleSim::imu_angular_rate() const {
  require_imu();
  const mjtNum* g = data_->sensordata + gyro_adr_;
  return {g[0], g[1], g[2]};
}

Eigen::Vector3d VehicleSim::imu_specific_force() const {
  require_imu();
  const mjtNum* a = data_->sensordata + accel_adr_;
  return {a[0], a[1], a[2]};
}

core::Pose3 VehicleSim::vehicle_pose3() const {
  const mjtNum* pos = data_->xpos + 3 * chassis_body_;
  const mjtNum* q = data_->xquat + 4 * chassis_body_;
  const core::Pose3 body{{pos[0], pos[1], pos[2]}, Eigen::Quaterniond(q[0], q[1], q[2], q[3])};
  return body.compose({{0.0, 0.0, -params_.wheel_radius_m}, Eigen::Quaterniond::Identity()});
}

VehicleTruth VehicleSim::truth() const {
  VehicleTruth t;
  const mjtNum* pos = data_->xpos + 3 * chassis_body_;
  const mjtNum* R = data_->xmat + 9 * chassis_body_;
  t.pose = {pos[0], pos[1], std::atan2(R[3], R[0])};
  // mjOBJ_XBODY: at the body frame's origin, the rear axle centre (mjOBJ_BODY would give the
  // velocity of the centre of mass, in the principal axes of inertia)
  mjtNum vel[6];
  mj_objectVelocity(model_, data_, mjOBJ_XBODY, chassis_body_, vel, 1);
  t.vx_mps = vel[3];
  t.vy_mps = vel[4];
  t.yaw_rate_rps = vel[2];
  t.steer_rad = steer_rad_;
  t.wheel_angle_rad = {data_->qpos[steer_qpos_[0]], data_->qpos[steer_qpos_[1]]};
  for (int c = 0; c < 4; ++c) {
    t.wheel_omega_rps[c] = data_->qvel[spin_qvel_[c]];
    t.wheel_spin_rad[c] = data_->qpos[spin_qpos_[c]];
    const mjtNum* k = data_->xpos + 3 * knuckle_body_[c];
    t.wheel_positions[c] = {k[0], k[1]};
  }
  return t;
}

std::vector<std::pair<double, double>> measure_yaw_gain(const vehicle_models::VehicleParams& params,
                                                        int points) {
  constexpr double kSpeedMps = 4.0;  // walking pace of a hairpin: the fight, not the grip
  constexpr double kSettleS = 4.0, kMeasureS = 3.0;
  std::vector<std::pair<double, double>> table = {{0.0, 1.0}};
  for (int i = 1; i <= points; ++i) {
    const double steer = params.max_steer_rad * i / points;
    VehicleSim car(params, {});
    double t = 0.0, yaw = 0.0, kinematic = 0.0;
    while (t < kSettleS + kMeasureS) {
      const VehicleTruth tr = car.truth();
      if (t >= kSettleS) {
        yaw += std::abs(tr.yaw_rate_rps);
        kinematic += std::hypot(tr.vx_mps, tr.vy_mps) * std::tan(steer) / params.wheelbase_m;
      }
      car.step({steer, std::clamp(3.0 * (kSpeedMps - tr.vx_mps), -5.0, 5.0), false}, false);
      t += car.timestep_s();
    }
    table.emplace_back(steer, kinematic > 0.0 ? yaw / kinematic : 1.0);
  }
  return table;
}

}  // namespace conesim::sim
