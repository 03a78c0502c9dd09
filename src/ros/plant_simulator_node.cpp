// plant_simulator node: see include/pmsm_param_id/ros/plant_simulator.hpp (parameters, topics).
#include "pmsm_param_id/io/config_error.hpp"
#include "pmsm_param_id/ros/plant_simulator.hpp"

int main(int argc, char** argv) {
  ros::init(argc, argv, "plant_simulator");
  ros::NodeHandle pnh("~");
  try {
    pmsm_param_id::PlantSimulator plant(pnh);
    plant.run();
    ros::WallDuration(plant.linger()).sleep();
  } catch (const std::exception& e) {  // a bad parameter or scenario: one FATAL line, status 1
    ROS_FATAL("%s", e.what());
    return 1;
  }
  return 0;
}
