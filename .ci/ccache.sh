# Sourced by the build scripts: compile through ccache where it is installed (the test
# dependencies bring it), with paths relative to the checkout so that another clone of the
# same sources (CI's) hits the same cache. Sets `launcher` for cmake's command line.
launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=)
if command -v ccache >/dev/null; then
  export CCACHE_BASEDIR=${CCACHE_BASEDIR:-$PWD} CCACHE_NOHASHDIR=${CCACHE_NOHASHDIR:-1}
  launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
fi
