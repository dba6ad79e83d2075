#pragma once
// The car in MuJoCo: builds the model from the vehicle parameters, turns driver commands into
// steering servo targets and wheel torques (rate limit, anti-Ackermann split, power limit,
// traction control, ABS, brakes, aero and rolling resistance), and reads the ground truth back.

#include <mujoco/mujoco.h>

#include <array>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "core/autonomy_types.hpp"
#include "core/geometry.hpp"
#include "core/measurements.hpp"
#include "tracks/ground.hpp"
#include "vehicle_models/vehicle_params.hpp"

namespace conesim::sim {

/// Exact state of the car, as only the harness (referee, evaluator) sees it.
struct VehicleTruth {
  /// Pose of the rear axle centre in the track frame.
  core::Pose2 pose;
  /// Velocity of the rear axle centre in the vehicle frame, m/s.
  double vx_mps = 0.0;
  double vy_mps = 0.0;
  double yaw_rate_rps = 0.0;
  /// Single-track steering angle now applied (after the rate limit), radians.
  double steer_rad = 0.0;
  /// Front wheel angles as MuJoCo has them, radians (left, right).
  std::array<double, 2> wheel_angle_rad{};
  /// Wheel spin rates fl, fr, rl, rr, rad/s.
  std::array<double, 4> wheel_omega_rps{};
  /// Centres of the four wheels' contact patches in the track frame.
  std::array<core::Vec2, 4> wheel_positions{};
  /// Accumulated spin angle of each wheel, radians (what the encoders count).
  std::array<double, 4> wheel_spin_rad{};
};

/// Owns the MuJoCo model and data of one car.
/// Loads MJCF text through MuJoCo's virtual file system; the caller owns the model
/// (mj_deleteModel). Throws std::runtime_error with MuJoCo's message when it cannot load.
mjModel* load_mjcf_model(const std::string& xml);

class VehicleSim {
 public:
  /// Builds the model on the ground (a MuJoCo height field unless flat) and places the rear
  /// axle centre at `start`, at rest, with its wheels on the ground. Throws std::runtime_error
  /// with MuJoCo's message if the model does not load.
  VehicleSim(const vehicle_models::VehicleParams& params, const core::Pose2& start,
             const tracks::GroundModel& ground = {});
  ~VehicleSim();
  VehicleSim(const VehicleSim&) = delete;
  VehicleSim& operator=(const VehicleSim&) = delete;

  /// Advances one physics step with the command held over the step. With `imu` false the step
  /// skips MuJoCo's sensors (nothing in the physics depends on them; a fifth of the step's cost)
  /// and the IMU reads are refused until a step that computes them.
  void step(const core::VehicleCommand& command, bool imu = true);

  /// The state after the last step.
  VehicleTruth truth() const;

  /// Full 3D pose of the vehicle frame (rear axle centre on the ground at design ride height,
  /// x forward, z up) in the track frame, pitch, roll and heave included. Sensors mount on it.
  core::Pose3 vehicle_pose3() const;

  /// What the IMU (gyro and accelerometer at the IMU site) measures exactly, vehicle frame, as
  /// computed by the last step (std::logic_error if that step skipped the sensors).
  Eigen::Vector3d imu_angular_rate() const;
  Eigen::Vector3d imu_specific_force() const;

  /// Physics step, seconds.
  double timestep_s() const;

  const mjModel* model() const { return model_; }
  const mjData* data() const { return data_; }
  const vehicle_models::VehicleParams& params() const { return params_; }
  /// The ground the car drives on (the sensors see the same).
  const tracks::GroundModel& ground() const { return ground_; }

 private:
  void apply_controls(const core::VehicleCommand& command);
  void require_imu() const;

  vehicle_models::VehicleParams params_;
  tracks::GroundModel ground_;
  mjModel* model_ = nullptr;
  mjData* data_ = nullptr;
  int chassis_body_ = -1;
  std::array<int, 4> knuckle_body_{};
  std::array<int, 2> steer_qpos_{};
  std::array<int, 4> spin_qvel_{};
  std::array<int, 4> spin_qpos_{};
  int gyro_adr_ = -1;
  int accel_adr_ = -1;
  std::array<int, 2> steer_actuator_{};
  std::array<int, 4> drive_actuator_{};
  double steer_rad_ = 0.0;
  // whether the last step computed the sensors
  bool imu_fresh_ = true;
};

/// The car's yaw gain over steering angle at low speed: the yaw rate at a held single-track angle
/// over the kinematic v tan(d) / L, measured by driving this car in MuJoCo at 4 m/s at each of
/// `points` angles evenly up to full lock (7 s of simulated time each, 0.06 s of CPU).
/// Pairs of (angle rad, gain) with (0, 1) first, angles rising: the steering tracker's table.
/// Anti-Ackermann front tyres fight at large angles, so the gain falls below 1 there.
std::vector<std::pair<double, double>> measure_yaw_gain(const vehicle_models::VehicleParams& params,
                                                        int points = 6);

}  // namespace conesim::sim
