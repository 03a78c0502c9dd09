// identifier node: see identifier_node.hpp and README (parameters, topics).
#include "pmsm_param_id/ros/identifier_node.hpp"
#include "pmsm_param_id/io/config_error.hpp"

int main(int argc, char** argv) {
  ros::init(argc, argv, "identifier");
  // Handles outlive the node object: if its constructor throws, ROS (and rosconsole) must still be
  // up to print the FATAL line; the last NodeHandle going away shuts both down.
  ros::NodeHandle nh, pnh("~");
  try {
    pmsm_param_id::IdentifierNode node{nh, pnh};
    ros::spin();
    const auto e = node.identifier().estimate();
    ROS_INFO("%s final: R_s = %.6g ohm, L_d = %.6g H, L_q = %.6g H, psi_f = %.6g Wb (%llu samples)", e.method.c_str(),
             e.parameters[0], e.parameters[1], e.parameters[2], e.parameters[3],
             static_cast<unsigned long long>(e.counters.used));
  } catch (const pmsm_param_id::ConfigError& e) {
    ROS_FATAL("%s", e.what());
    return 1;
  } catch (const std::exception& e) {  // anything else: one FATAL line and status 1, never an abort
    ROS_FATAL("%s", e.what());
    return 1;
  }
  return 0;
}
