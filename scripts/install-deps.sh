#!/usr/bin/env bash
# Installs springfit's build and test dependencies from Debian's packages.
# Idempotent: packages already present are left alone, and apt is not touched at all
# when everything is installed.
#
#   bash scripts/install-deps.sh          everything: the programs, the tests, the benchmarks
#   bash scripts/install-deps.sh --main   what builds and runs springfit and springfitd alone
#                                          (the README's first command: about a third of the
#                                          download, bench/RESULTS.md "The first command")
set -euo pipefail

main_only=false
case "${1:-}" in
  "") ;;
  --main) main_only=true ;;
  *) echo "install-deps: unknown argument '$1' (none, or --main)" >&2; exit 2 ;;
esac

# What the two programs need to build and run.
main_packages=(
  build-essential cmake pkg-config
  libeigen3-dev            # linear algebra, sparse factorisation
  libsuitesparse-dev       # CHOLMOD: supernodal sparse Cholesky (strategy direct at scale)
  liblapack-dev            # band Cholesky of the small equilibrium systems
  libnanoflann-dev         # k-d tree: candidates and coincident nodes in O(n log n)
  libboost-dev             # Asio (header-only) for networking and thread pools
  nlohmann-json3-dev       # JSON
  libsqlite3-dev libsqlitecpp-dev
  libpqxx-dev              # the shared PostgreSQL store (libpq's C++ client)
  libcli11-dev             # command line
  libspdlog-dev libfmt-dev # logging
  libgmsh-dev              # the Gmsh library: writes (and reads) Gmsh's mesh files
)

# What the tests and benchmarks need besides.
test_packages=(
  postgresql               # a private server the store and multi-daemon tests start
  chromium                 # headless, loads the dashboard in tests/daemon/dashboard_test.py
  libgtest-dev libbenchmark-dev
  clang libclang-rt-14-dev # libFuzzer targets and sanitizer runtime
  clang-format             # the format check (tests/format_check.sh)
  git                      # the format check lists the tracked files
  python3                  # the end-to-end tests drive the CLI and the daemon with it
  python3-pip              # pip install ./python (the Python client; its build backend is its own)
  calculix-ccx             # CalculiX: independent answers for the FEM reference tests
  gmsh                     # meshes a 2D shape for the FEM reference tests; reads exported .msh
  python3-meshio           # an independent reader of the exported .vtk, .vtu, .msh (tests/io)
  python3-vtk9 python3-gmsh  # VTK's and Gmsh's own readers of the exports (tests/io/real_readers_test.py)
  python3-venv             # the Python client installed by pip into a plain venv (tests/python)
  python3-scipy            # the independent evaluator bench/generalization.py (sparse and bounded fits)
)

packages=("${main_packages[@]}")
$main_only || packages+=("${test_packages[@]}")

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q 'install ok installed' || missing+=("$p")
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#packages[@]} packages present"
  exit 0
fi

sudo=""
[ "$(id -u)" -eq 0 ] || sudo="sudo"
echo "install-deps: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$sudo apt-get update -qq
$sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"
