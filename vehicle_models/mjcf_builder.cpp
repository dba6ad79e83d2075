#include "vehicle_models/mjcf_builder.hpp"

#include <algorithm>
#include <sstream>

#include "vehicle_models/cone_meshes.hpp"

namespace conesim::vehicle_models {

namespace {

constexpr double kGravity = 9.81;
constexpr double kKnuckleMassKg = 2.0;
// depth of a height field's box below its lowest point, metres
constexpr double kHeightFieldBaseM = 1.0;

}  // namespace

std::string build_mjcf(const VehicleParams& p, const MjcfOptions& o) {
  std::ostringstream x;
  x.precision(10);
  const bool hfield = o.ground.nrow > 1 && o.ground.ncol > 1;

  // masses: the chassis carries what the wheels and knuckles do not
  const double unsprung_kg = 4.0 * (p.wheel_mass_kg + kKnuckleMassKg);
  const double chassis_kg = p.mass_kg - unsprung_kg;
  const double cog_x = p.cog_from_rear_axle_m();
  const double cog_z = p.cog_height_m - p.wheel_radius_m;  // above the body origin
  const double half_track = 0.5 * p.track_m;

  // yaw inertia of the chassis: the total less what the wheels contribute at their corners
  const double wheel_yaw = 4.0 * (p.wheel_mass_kg + kKnuckleMassKg) *
                           (0.25 * p.wheelbase_m * p.wheelbase_m + half_track * half_track);
  const double izz = std::max(0.2 * p.yaw_inertia_kgm2, p.yaw_inertia_kgm2 - wheel_yaw);
  const double ixx = 0.35 * izz;
  const double iyy = 0.85 * izz;

  // spring preload per corner: each spring carries its share of the chassis weight at q = 0
  const double front_share = p.front_mass_fraction;
  const double spring_force[2] = {0.5 * chassis_kg * kGravity * front_share,
                                  0.5 * chassis_kg * kGravity * (1.0 - front_share)};

  // wheel inertia about the spin axis (a thin disc) and about the other axes
  const double r = p.wheel_radius_m;
  const double i_spin = 0.5 * p.wheel_mass_kg * r * r;
  const double i_other = 0.25 * p.wheel_mass_kg * r * r;

  x << "<mujoco model=\"conesim-car\">\n"
    << "  <compiler angle=\"radian\"/>\n"
    << "  <option timestep=\"" << o.timestep_s
    << "\" cone=\"elliptic\" impratio=\"1\" integrator=\"Euler\" gravity=\"0 0 -9.81\" "
    // the tyres touch only the ground: the four pairs below, no broad phase
    << "collision=\"predefined\"/>\n"
    // a height field gives a tyre a contact per prism it touches: room for them
    << (hfield ? "  <size nconmax=\"256\" njmax=\"1024\" nstack=\"200000\"/>\n"
               : "  <size nconmax=\"32\" njmax=\"160\" nstack=\"20000\"/>\n")
    << "  <visual>\n"
    << "    <global offwidth=\"" << o.offscreen_width_px << "\" offheight=\""
    << o.offscreen_height_px << "\"/>\n"
    << "    <quality shadowsize=\"0\" offsamples=\"0\"/>\n"
    << "    <headlight ambient=\"0.45 0.45 0.45\" diffuse=\"0.55 0.55 0.55\" specular=\"0 0 0\"/>\n"
    << "    <map znear=\"0.05\" zfar=\"400\"/>\n"
    << "  </visual>\n"
    << "  <default>\n"
    << "    <geom condim=\"3\" friction=\"" << p.tyre_friction
    << " 0.005 0.0001\" solimp=\"0 0.95 0.001\" solref=\"0.02 1\"/>\n"
    << "  </default>\n"
    << "  <asset>\n"
    << "    <texture name=\"sky\" type=\"skybox\" builtin=\"gradient\" rgb1=\"0.55 0.7 0.9\" "
       "rgb2=\"0.85 0.9 0.95\" width=\"256\" height=\"256\"/>\n"
    << "    <texture name=\"asphalt\" type=\"2d\" builtin=\"flat\" rgb1=\"0.3 0.3 0.32\" "
       "rgb2=\"0.27 0.27 0.29\" mark=\"random\" random=\"0.3\" markrgb=\"0.36 0.36 0.38\" "
       "width=\"512\" height=\"512\"/>\n"
    << "    <material name=\"asphalt\" texture=\"asphalt\" texrepeat=\"60 60\" "
       "specular=\"0\" shininess=\"0\" reflectance=\"0\"/>\n"
    << "    <material name=\"body\" rgba=\"0.75 0.08 0.08 1\" specular=\"0.2\"/>\n"
    << "    <material name=\"tyre\" rgba=\"0.08 0.08 0.08 1\" specular=\"0\"/>\n"
    // cone meshes and textures for the camera: assets only, no geom uses them (not physics)
    << cone_assets();
  if (hfield)
    x << "    <hfield name=\"ground\" nrow=\"" << o.ground.nrow << "\" ncol=\"" << o.ground.ncol
      << "\" size=\"" << o.ground.half_x_m << " " << o.ground.half_y_m << " "
      << o.ground.elevation_m << " " << kHeightFieldBaseM << "\"/>\n";
  x << "  </asset>\n"
    << "  <worldbody>\n"
    << (hfield
            ? ""
            : "    <geom name=\"ground\" type=\"plane\" size=\"0 0 1\" material=\"asphalt\"/>\n");
  if (hfield)
    x << "    <geom name=\"ground\" type=\"hfield\" hfield=\"ground\" pos=\"" << o.ground.centre_x_m
      << " " << o.ground.centre_y_m << " " << o.ground.base_z_m << "\" material=\"asphalt\"/>\n";
  x << "    <body name=\"" << MjcfNames::kChassis << "\" pos=\"0 0 " << r << "\">\n"
    << "      <freejoint name=\"" << MjcfNames::kChassis << "\"/>\n"
    << "      <inertial pos=\"" << cog_x << " 0 " << cog_z << "\" mass=\"" << chassis_kg
    << "\" diaginertia=\"" << ixx << " " << iyy << " " << izz
    << "\"/>\n"
    // visual body: monocoque, nose, front wing and main hoop (no collisions)
    << "      <geom name=\"monocoque\" type=\"box\" size=\"" << 0.5 * p.wheelbase_m << " 0.3 0.2\" "
    << "pos=\"" << 0.5 * p.wheelbase_m
    << " 0 0.05\" material=\"body\" contype=\"0\" "
       "conaffinity=\"0\" mass=\"0\"/>\n"
    << "      <geom name=\"front_wing\" type=\"box\" size=\"0.1 " << 0.5 * p.width_m
    << " 0.02\" pos=\"" << p.front_overhang_from_rear_axle_m - 0.1
    << " 0 -0.15\" "
       "material=\"body\" contype=\"0\" conaffinity=\"0\" mass=\"0\"/>\n"
    << "      <geom name=\"main_hoop\" type=\"box\" size=\"0.04 0.25 0.35\" pos=\""
    << 0.35 * p.wheelbase_m
    << " 0 0.45\" material=\"body\" contype=\"0\" conaffinity=\"0\" "
       "mass=\"0\"/>\n"
    << "      <site name=\"" << MjcfNames::kImuSite << "\" pos=\"" << cog_x << " 0 " << cog_z
    << "\" size=\"0.02\"/>\n";

  // the four corners: knuckle with suspension (and steering at the front), wheel with spin hinge
  for (int c = 0; c < 4; ++c) {
    const std::string name = MjcfNames::kCorners[c];
    const bool front = c < 2;
    const double cx = front ? p.wheelbase_m : 0.0;
    const double cy = (c % 2 == 0) ? half_track : -half_track;
    const double springref = -spring_force[front ? 0 : 1] / p.spring_n_per_m;
    x << "      <body name=\"knuckle_" << name << "\" pos=\"" << cx << " " << cy << " 0\">\n"
      << "        <inertial pos=\"0 0 0\" mass=\"" << kKnuckleMassKg
      << "\" diaginertia=\"0.01 0.01 0.01\"/>\n"
      << "        <joint name=\"susp_" << name << "\" type=\"slide\" axis=\"0 0 1\" "
      << "limited=\"true\" range=\"" << -p.suspension_travel_m << " " << p.suspension_travel_m
      << "\" stiffness=\"" << p.spring_n_per_m << "\" springref=\"" << springref
      << "\" damping=\"" << p.damper_ns_per_m << "\"/>\n";
    if (front) {
      x << "        <joint name=\"steer_" << name << "\" type=\"hinge\" axis=\"0 0 1\" "
        << "limited=\"true\" range=\"" << -1.3 * p.max_steer_rad - 0.2 << " "
        << 1.3 * p.max_steer_rad + 0.2 << "\" damping=\"30\" armature=\"0.05\"/>\n";
    }
    x << "        <body name=\"wheel_" << name << "\">\n"
      << "          <inertial pos=\"0 0 0\" mass=\"" << p.wheel_mass_kg << "\" diaginertia=\""
      << i_other << " " << i_spin << " " << i_other << "\"/>\n"
      << "          <joint name=\"spin_" << name << "\" type=\"hinge\" axis=\"0 1 0\" "
      << "armature=\"" << p.motor_rotor_inertia_kgm2 << "\"/>\n"
      << "          <geom name=\"tyre_" << name << "\" type=\"ellipsoid\" size=\"" << r << " " << r
      << " " << 0.5 * p.wheel_width_m << "\" zaxis=\"0 1 0\" material=\"tyre\" mass=\"0\"/>\n"
      << "        </body>\n"
      << "      </body>\n";
  }
  x << "    </body>\n"
    << "  </worldbody>\n";

  // the contacts: each tyre on the ground, with the parameters the geoms' defaults mix to
  // (condim 3, the tyre friction sliding, the small torsional and rolling friction)
  x << "  <contact>\n";
  for (int c = 0; c < 4; ++c) {
    x << "    <pair geom1=\"ground\" geom2=\"tyre_" << MjcfNames::kCorners[c]
      << "\" condim=\"3\" friction=\"" << p.tyre_friction << " " << p.tyre_friction
      << " 0.005 0.0001 0.0001\" solimp=\"0 0.95 0.001 0.5 2\" solref=\"0.02 1\"/>\n";
  }
  x << "  </contact>\n";

  // actuators: steering servos at the front, one motor per wheel (drive and brake summed)
  x << "  <actuator>\n";
  for (int c = 0; c < 2; ++c) {
    const std::string name = MjcfNames::kCorners[c];
    x << "    <position name=\"steer_" << name << "\" joint=\"steer_" << name
      << "\" kp=\"3000\" forcelimited=\"true\" forcerange=\"-400 400\"/>\n";
  }
  for (int c = 0; c < 4; ++c) {
    const std::string name = MjcfNames::kCorners[c];
    x << "    <motor name=\"drive_" << name << "\" joint=\"spin_" << name << "\" gear=\"1\"/>\n";
  }
  x << "  </actuator>\n";

  // sensors for the sensor models: IMU, steering angles, wheel speeds
  x << "  <sensor>\n"
    << "    <gyro name=\"gyro\" site=\"" << MjcfNames::kImuSite << "\"/>\n"
    << "    <accelerometer name=\"accelerometer\" site=\"" << MjcfNames::kImuSite << "\"/>\n";
  for (int c = 0; c < 2; ++c) {
    const std::string name = MjcfNames::kCorners[c];
    x << "    <jointpos name=\"steer_" << name << "\" joint=\"steer_" << name << "\"/>\n";
  }
  for (int c = 0; c < 4; ++c) {
    const std::string name = MjcfNames::kCorners[c];
    x << "    <jointvel name=\"wheel_speed_" << name << "\" joint=\"spin_" << name << "\"/>\n";
  }
  x << "  </sensor>\n"
    << "</mujoco>\n";
  return x.str();
}

}  // namespace conesim::vehicle_models
