#!/usr/bin/env bash
# With only an installed Talus (PREFIX): a `talus plugin new` project and
# the installed example build and pass their tests. No source tree, no
# TALUS_PLUGIN_PATH, a HOME of its own.
#   plugin_project.sh PREFIX WORK
set -euo pipefail
prefix=$1 work=$2
rm -rf "$work" && mkdir -p "$work/home"
export HOME=$work/home
unset TALUS_PLUGIN_PATH XDG_DATA_HOME
export PATH=$prefix/bin:$PATH
cd "$work"

talus plugin new my_soil
cmake -S my_soil -B my_soil/build -DCMAKE_PREFIX_PATH="$prefix" > my_soil.configure.log
cmake --build my_soil/build > my_soil.build.log
ctest --test-dir my_soil/build --output-on-failure

example=$prefix/share/doc/talus/examples/00_out_of_tree_plugin
cmake -S "$example" -B example -DCMAKE_PREFIX_PATH="$prefix" > example.configure.log
cmake --build example > example.build.log
ctest --test-dir example --output-on-failure
# The installed talus finds the shipped plugins beside itself.
talus plugin list | grep -q "^mohr_coulomb"
talus plugin list | grep -q "^umat "
echo "plugin project and example: ok"
