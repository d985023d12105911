// Print what libsdformat (the SDF parser Gazebo uses) makes of SDF files, one fact a line, so that
// tests/test_sdf_sdformat.py can compare it with pytest-ddenv's import:
//   FILE <path>
//   ERROR <message>                                (then nothing else for that file)
//   WORLD <name> models=<n> lights=<n> actors=<n>
//   MODEL <scoped name> static=<0|1> joints=<n> pose=<x y z roll pitch yaw in the world>
//   LINK <scoped name> pose=<x y z roll pitch yaw in the world> collisions=<n>
//   COLLISION <scoped name> geometry=<box|cylinder|sphere|capsule|mesh|plane|heightmap|ellipsoid|other>
//             pose=<x y z roll pitch yaw in the world>
// Scoped names join nested models with "::". `model://` URIs are found through SDF_PATH.
#include <sdf/sdf.hh>
#include <iomanip>
#include <iostream>
#include <string>

using Pose = ignition::math::Pose3d;

static void print_pose(const Pose& p) {
  std::cout << " pose=" << p.Pos().X() << " " << p.Pos().Y() << " " << p.Pos().Z() << " " << p.Rot().Roll()
            << " " << p.Rot().Pitch() << " " << p.Rot().Yaw();
}

static const char* geometry_name(sdf::GeometryType type) {
  switch (type) {
    case sdf::GeometryType::BOX: return "box";
    case sdf::GeometryType::CYLINDER: return "cylinder";
    case sdf::GeometryType::SPHERE: return "sphere";
    case sdf::GeometryType::CAPSULE: return "capsule";
    case sdf::GeometryType::MESH: return "mesh";
    case sdf::GeometryType::PLANE: return "plane";
    case sdf::GeometryType::HEIGHTMAP: return "heightmap";
    case sdf::GeometryType::ELLIPSOID: return "ellipsoid";
    default: return "other";
  }
}

static void dump_model(const sdf::Model* model, const std::string& prefix, const Pose& world_of_model) {
  const std::string name = prefix + model->Name();
  std::cout << "MODEL " << name << " static=" << model->Static() << " joints=" << model->JointCount();
  print_pose(world_of_model);
  std::cout << "\n";
  for (uint64_t i = 0; i < model->LinkCount(); ++i) {
    const sdf::Link* link = model->LinkByIndex(i);
    Pose in_model;
    sdf::Errors errors = link->SemanticPose().Resolve(in_model, "__model__");
    for (auto& e : errors) std::cout << "ERROR " << e.Message() << "\n";
    std::cout << "LINK " << name << "::" << link->Name();
    print_pose(world_of_model * in_model);
    std::cout << " collisions=" << link->CollisionCount() << "\n";
    for (uint64_t c = 0; c < link->CollisionCount(); ++c) {
      const sdf::Collision* collision = link->CollisionByIndex(c);
      Pose in_link;
      sdf::Errors collision_errors = collision->SemanticPose().Resolve(in_link, link->Name());
      for (auto& e : collision_errors) std::cout << "ERROR " << e.Message() << "\n";
      std::cout << "COLLISION " << name << "::" << link->Name() << "::" << collision->Name()
                << " geometry=" << geometry_name(collision->Geom()->Type());
      print_pose(world_of_model * in_model * in_link);
      std::cout << "\n";
    }
  }
  for (uint64_t i = 0; i < model->ModelCount(); ++i) {
    const sdf::Model* nested = model->ModelByIndex(i);
    Pose in_parent;
    sdf::Errors errors = nested->SemanticPose().Resolve(in_parent, "__model__");
    for (auto& e : errors) std::cout << "ERROR " << e.Message() << "\n";
    dump_model(nested, name + "::", world_of_model * in_parent);
  }
}

int main(int argc, char** argv) {
  std::cout << std::setprecision(17);
  int failures = 0;
  for (int i = 1; i < argc; ++i) {
    std::cout << "FILE " << argv[i] << "\n";
    sdf::Root root;
    sdf::Errors errors = root.Load(argv[i]);
    if (!errors.empty()) {
      ++failures;
      for (auto& e : errors) std::cout << "ERROR " << e.Message() << "\n";
      continue;
    }
    if (root.WorldCount() == 0) {
      if (root.Model() != nullptr) {
        Pose pose;
        root.Model()->SemanticPose().Resolve(pose);
        dump_model(root.Model(), "", pose);
      }
      continue;
    }
    const sdf::World* world = root.WorldByIndex(0);
    std::cout << "WORLD " << world->Name() << " models=" << world->ModelCount() << " lights=" << world->LightCount()
              << " actors=" << world->ActorCount() << "\n";
    for (uint64_t m = 0; m < world->ModelCount(); ++m) {
      const sdf::Model* model = world->ModelByIndex(m);
      Pose pose;
      sdf::Errors pose_errors = model->SemanticPose().Resolve(pose, "world");
      for (auto& e : pose_errors) std::cout << "ERROR " << e.Message() << "\n";
      dump_model(model, "", pose);
    }
  }
  return failures ? 1 : 0;
}
