// The identifier and the plant simulator as nodelets: many of them in one manager process share
// its threads, and a batch published by a plant reaches an identifier in the same manager as a
// pointer (no serialisation). Parameters and topics as the nodes' (identifier_node.hpp,
// plant_simulator.hpp).
#include <nodelet/nodelet.h>
#include <pluginlib/class_list_macros.hpp>

#include <memory>

#include "pmsm_param_id/ros/identifier_node.hpp"
#include "pmsm_param_id/ros/plant_simulator.hpp"

namespace pmsm_param_id {

class IdentifierNodelet : public nodelet::Nodelet {
  void onInit() override {
    try {
      node_ = std::make_unique<IdentifierNode>(getNodeHandle(), getPrivateNodeHandle());
    } catch (const std::exception& e) {  // a nodelet cannot exit: it says why and stays idle
      NODELET_FATAL("%s (this identifier does nothing)", e.what());
    }
  }
  std::unique_ptr<IdentifierNode> node_;
};

class PlantSimulatorNodelet : public nodelet::Nodelet {
  void onInit() override {
    try {
      plant_ = std::make_unique<PlantSimulator>(getPrivateNodeHandle());
      plant_->advertise();  // here, not on the pacer's thread (PlantSimulator::advertise)
    } catch (const std::exception& e) {
      NODELET_FATAL("%s (this plant does nothing)", e.what());
      return;
    }
    // Paced by the process's one pacer thread with every other plant of this manager: one wake-up
    // per batch period for all of them (doc/performance.md, "Fleet").
    pacer_ = PlantPacer::shared();
    pacer_->add(plant_.get());
  }

 public:
  ~PlantSimulatorNodelet() override {
    if (pacer_ && plant_) pacer_->remove(plant_.get());  // no batch of it in flight after this
  }

 private:
  std::shared_ptr<PlantPacer> pacer_;
  std::unique_ptr<PlantSimulator> plant_;
};

}  // namespace pmsm_param_id

PLUGINLIB_EXPORT_CLASS(pmsm_param_id::IdentifierNodelet, nodelet::Nodelet)
PLUGINLIB_EXPORT_CLASS(pmsm_param_id::PlantSimulatorNodelet, nodelet::Nodelet)
