# The host-cost suite's rows (sourced by bench/host_cost.sh and bench/host_phases.sh): each row
# name and the host-sim command line it runs, without output options. One definition, so
# that a row means the same in every table that names it.
# shellcheck disable=SC2034  # used by the scripts that source this file
ALL_ROWS="cornell-128 cornell-128-t1 cornell-256 cornell-512 teapot-256 bureau1-256 bureau2-256 classe-128 classe-light-32 radiosity-64"
declare -A ARGS=(
  [cornell-128]="render --n 128"
  [cornell-128-t1]="render --n 128 --threads 1"
  [cornell-256]="render --n 256"
  [cornell-512]="render --n 512"
  [teapot-256]="render teapot-floor --n 256"
  [bureau1-256]="render bureau1 --n 256"
  [bureau2-256]="render bureau2 --n 256"
  [classe-128]="render classe --n 128"
  [classe-light-32]="light classe --n 32"
  [radiosity-64]="radiosity cornell --n 64 --residual 0.01"
)
