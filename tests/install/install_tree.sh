#!/usr/bin/env bash
# Installs the build tree under test into PREFIX (a fresh folder): the
# fixture of the install and docs tests, which then use only that prefix.
#   install_tree.sh BUILD_DIR PREFIX
set -euo pipefail
build=$1 prefix=$2
rm -rf "$prefix"
cmake --install "$build" --prefix "$prefix" > /dev/null
test -x "$prefix/bin/talus"
echo "installed into $prefix"
