// terrain-view: thin shell over run_viewer() (viewer/src/app.h).
#include "app.h"
#include "image_io.h"

#include "cli_checks.h"

int main(int argc, char** argv) {
  return terrain::cli::guarded_main("terrain-view", [&] {
    terrain::view::ViewerOptions options;
    int exit_code = 0;
    if (!terrain::view::parse_viewer_options(argc, argv, options, exit_code)) return exit_code;
    return terrain::view::run_viewer(options, terrain::view::write_png);
  });
}
