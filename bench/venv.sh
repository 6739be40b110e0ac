# Shared by the bench scripts that plot or compare in Python: a venv under bench-out/ (ignored
# by git; none of it is a dependency of the product). Source it, then call
# `bench_python PACKAGE...`: it prints the venv's python after making sure the packages import
# (their import names; installed from PyPI on first use).
bench_python() {
  local repo venv
  repo=$(git -C "$(dirname "${BASH_SOURCE[0]}")" rev-parse --show-toplevel)
  venv=$repo/bench-out/venv
  [ -x "$venv/bin/python" ] || python3 -m venv "$venv" >&2
  local p
  for p in "$@"; do
    "$venv/bin/python" -c "import $p" 2> /dev/null || "$venv/bin/pip" install -q "$p" >&2
  done
  echo "$venv/bin/python"
}
