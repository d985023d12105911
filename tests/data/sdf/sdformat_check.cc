// Validate SDF files with libsdformat (the parser Gazebo uses): load, report errors, count models.
#include <sdf/sdf.hh>
#include <iostream>
int main(int argc, char** argv) {
  int failures = 0;
  for (int i = 1; i < argc; ++i) {
    sdf::Root root;
    sdf::Errors errors = root.Load(argv[i]);
    if (!errors.empty()) {
      ++failures;
      std::cout << argv[i] << ": " << errors.size() << " error(s)\n";
      for (auto& e : errors) std::cout << "  " << e.Message() << "\n";
      continue;
    }
    const sdf::World* world = root.WorldCount() ? root.WorldByIndex(0) : nullptr;
    std::cout << argv[i] << ": ok, " << (world ? world->ModelCount() : 0) << " models\n";
  }
  return failures ? 1 : 0;
}
