#!/usr/bin/env bash
# Installs the build into a temporary prefix and uses it as a user and a developer would:
# the installed `octshape --version`, its manual page, the docs; a 30-line CMake project that
# finds libmesh with find_package(octshape CONFIG) and links octshape::mesh; then the .deb from
# `cpack -G DEB`: its contents, its computed dependencies, and apt's verdict on installing it.
# Usage: install_test.sh BUILD_DIR SOURCE_DIR
set -euo pipefail
build=$(cd "$1" && pwd)
src=$(cd "$2" && pwd)
T=$(mktemp -d)
trap 'rm -rf "$T"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }

echo "== cmake --install $build --prefix PREFIX"
cmake --install "$build" --prefix "$T/prefix" >"$T/install.log"
for f in bin/octshape share/man/man1/octshape.1 share/doc/octshape/README.md \
         share/doc/octshape/LICENSE share/doc/octshape/CITATION.cff \
         share/doc/octshape/outputs.md share/doc/octshape/licences.md \
         share/octshape/workflow/Snakefile include/octshape/mesh/rofi.h \
         include/octshape/error.h include/octshape/version.h lib/liboctshape_mesh.a \
         lib/cmake/octshape/octshapeConfig.cmake lib/cmake/octshape/octshapeTargets.cmake; do
  [ -e "$T/prefix/$f" ] || fail "not installed: $f"
done
# Nothing private of the build tree leaks into the installed tree.
if grep -rqs --binary-files=without-match "$build" "$T/prefix/lib/cmake" "$T/prefix/share"; then
  fail "the installed files name the build tree"
fi
version=$("$T/prefix/bin/octshape" --version)
echo "installed: $version"
want=$(sed -n 's/^project(octshape VERSION \([0-9.]*\).*/\1/p' "$src/CMakeLists.txt")
[[ $version == "octshape $want"* ]] || fail "--version says '$version', the project is $want"
grep -q '^\.TH OCTSHAPE 1' "$T/prefix/share/man/man1/octshape.1" || fail "man page has no .TH"

echo "== a consumer project: find_package(octshape CONFIG), octshape::mesh"
cmake -S "$src/tests/install/consumer" -B "$T/consumer" -G Ninja -DCMAKE_BUILD_TYPE=Release \
  -DCMAKE_PREFIX_PATH="$T/prefix" >"$T/consumer.log" || { cat "$T/consumer.log"; fail "configure"; }
cmake --build "$T/consumer" >>"$T/consumer.log" || { cat "$T/consumer.log"; fail "build"; }
"$T/consumer/consumer" || fail "the consumer's denoised mesh is not closer to the plane"

echo "== cpack -G DEB"
(cd "$T" && cpack -G DEB --config "$build/CPackConfig.cmake" -B "$T/pkg" >"$T/cpack.log") ||
  { cat "$T/cpack.log"; fail "cpack"; }
deb=$(ls "$T"/pkg/octshape_*.deb)
dpkg-deb -I "$deb"
depends=$(dpkg-deb -f "$deb" Depends)
# Computed by dpkg-shlibdeps from what the executable loads: the C library, VTK, OpenCV's
# core, libtiff, libcrypto must be there; nothing of the build tree or a -dev package.
for lib in libc6 libvtk libopencv-core libtiff libssl; do
  [[ $depends == *"$lib"* ]] || fail "Depends lacks $lib: $depends"
done
[[ $depends != *"-dev"* ]] || fail "Depends names a -dev package: $depends"
dpkg-deb -c "$deb" >"$T/contents"
for f in ./usr/bin/octshape ./usr/share/man/man1/octshape.1 ./usr/share/doc/octshape/README.md \
         ./usr/include/octshape/mesh/rofi.h ./usr/lib/cmake/octshape/octshapeConfig.cmake; do
  grep -q " $f\$" "$T/contents" || fail ".deb lacks $f"
done
echo "the .deb holds $(wc -l <"$T/contents") entries"
# apt resolves the dependencies against this machine's Debian (simulated: nothing installed).
if command -v apt-get >/dev/null; then
  apt-get install --simulate -qq "$deb" >"$T/apt.log" 2>&1 || { cat "$T/apt.log"; fail "apt"; }
  echo "apt-get install --simulate: ok"
fi
echo "install test passed"
