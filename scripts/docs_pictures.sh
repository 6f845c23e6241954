#!/usr/bin/env bash
# Regenerates every picture of the README and the site (docs/img/) from the
# shipped scenes, their reports and the Python examples, with this checkout's
# build:
#
#   scripts/docs_pictures.sh [REEB]      # REEB: default target/release/reeb
#
# Scenes run on the CPU (their pictures are then the same on every machine
# but for text rendering); reports on the backends their scene lists, so
# their timing pictures are this machine's. The Python examples need the
# package (pip install "./python[examples]") in the python3 on the PATH, or
# PYTHON=... The one picture made elsewhere is heyoka_work_precision.png:
# scripts/compare_heyoka.sh draws it (PNG=docs/img/heyoka_work_precision.png)
# where heyoka.py is installed.
set -euo pipefail
cd "$(dirname "$0")/.."
reeb="$(realpath "${1:-target/release/reeb}")"
python="${PYTHON:-python3}"
work=target/docs-pictures
img=docs/img
mkdir -p "$work"

# docs/img/NAME.png  <-  SCENE's output picture
scene_pictures=(
  "damped_oscillator            damped_oscillator                trajectory"
  "duffing                      duffing                          poincare"
  "forced_van_der_pol           forced_van_der_pol               bifurcation"
  "forced_van_der_pol_lyapunov  forced_van_der_pol_lyapunov      lyapunov_1"
  "henon_heiles_escape          henon_heiles_escape              status_step"
  "henon_heiles_megno           henon_heiles_megno               megno"
  "henon_heiles_sali            henon_heiles_sali                sali"
  "kepler                       kepler                           trajectory"
  "kepler_large_step            kepler_large_step                trajectory"
  "lane_emden                   lane_emden                       trajectory"
  "lienard_quartic              lienard_quartic                  trajectory"
  "magnetic_pendulum_basins     magnetic_pendulum_basins         basins"
  "forced_double_well_basins_fractions  forced_double_well_basins  basin_fractions"
  "spin_orbit_background        spin_orbit_background            poincare"
  "spin_orbit_capture           spin_orbit_capture               trajectory"
  "spin_orbit_capture_statistics           spin_orbit_capture_statistics  resonance"
  "spin_orbit_capture_statistics_fractions spin_orbit_capture_statistics  capture"
  "spin_orbit_capture_statistics_mean      spin_orbit_capture_statistics  mean_p"
  "spin_orbit_capture_basins    spin_orbit_capture_basins        basins"
  "spin_orbit_dense             spin_orbit_dense                 poincare"
  "spin_orbit_fli               spin_orbit_fli                   fli"
  "spin_orbit_fli_poincare      spin_orbit_fli                   poincare_fli"
  "spin_orbit_fli_running       spin_orbit_fli                   trajectory_fli"
  "spin_orbit_nonresonant       spin_orbit_nonresonant           poincare"
  "spin_orbit_resonant_lambda0.001  spin_orbit_resonant_lambda0.001  poincare"
  "spin_orbit_resonant_lambda0.01   spin_orbit_resonant_lambda0.01   poincare"
  "spin_orbit_resonant_lambda0.1    spin_orbit_resonant_lambda0.1    poincare"
  "spin_orbit_resonant_lambda0.2    spin_orbit_resonant_lambda0.2    poincare"
  "van_der_pol_stability        van_der_pol_stability            cycle_amplitude"
  "van_der_pol_stiff            van_der_pol_stiff                trajectory"
)
# docs/img/NAME.png  <-  a report of SCENE (work-precision or stability)
report_pictures=(
  "report_damped_work_precision      work-precision  damped_oscillator_work_precision   work_precision"
  "report_damped_error_vs_dt         work-precision  damped_oscillator_work_precision   error_vs_dt"
  "report_kepler_error_vs_time       work-precision  kepler_work_precision              error_vs_time"
  "report_forced_vdp_work_precision  work-precision  forced_van_der_pol_work_precision  work_precision"
  "report_stability_f32              stability       van_der_pol_stability_report       stability_f32"
  "report_stability_f64              stability       van_der_pol_stability_report       stability_f64"
)
# docs/img/NAME.png  <-  python/examples/SCRIPT.py --out
example_pictures=(
  "python_van_der_pol_stability  van_der_pol_stability"
  "python_spin_orbit_portrait    spin_orbit_portrait"
  "python_work_precision         work_precision"
)

copy() { # FROM NAME
  [ -f "$1" ] || { echo "error: $1 was not written (the table above names a picture reeb no longer draws)" >&2; exit 1; }
  cp "$1" "$img/$2.png"
  echo "$img/$2.png  <-  $1"
}

declare -A ran=()
for row in "${scene_pictures[@]}"; do
  read -r name scene picture <<<"$row"
  if [ -z "${ran[$scene]:-}" ]; then
    "$reeb" run "scenes/$scene.toml" --backend cpu --out "$work/$scene" --force >"$work/$scene.log" 2>&1 \
      || { echo "error: scenes/$scene.toml failed, see $work/$scene.log" >&2; exit 1; }
    ran[$scene]=1
  fi
  copy "$work/$scene/$picture.png" "$name"
done

declare -A reported=()
for row in "${report_pictures[@]}"; do
  read -r name kind scene picture <<<"$row"
  out="$work/$scene-$kind"
  if [ -z "${reported[$out]:-}" ]; then
    "$reeb" report "$kind" "scenes/$scene.toml" --out "$out" --force >"$out.log" 2>&1 \
      || { echo "error: reeb report $kind scenes/$scene.toml failed, see $out.log" >&2; exit 1; }
    reported[$out]=1
  fi
  copy "$out/$picture.png" "$name"
done

for row in "${example_pictures[@]}"; do
  read -r name script <<<"$row"
  "$python" "python/examples/$script.py" --out "$work/$script.png" >"$work/$script.log" 2>&1 \
    || { echo "error: python/examples/$script.py failed, see $work/$script.log" >&2; exit 1; }
  copy "$work/$script.png" "$name"
done
echo "every picture of docs/img but heyoka_work_precision.png regenerated"
