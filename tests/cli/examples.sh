#!/usr/bin/env bash
# Tests of the example scenes, the demo and the numbers the documentation
# quotes about them.
#
#   examples.sh PSYS SRCDIR EXAMPLE.json...   each scene: `psys check` and a
#                                             short `psys run --steps 50`, exit 0,
#                                             finite, well-formed CSV
#   examples.sh PSYS SRCDIR --all             the same for every examples/*.json
#   examples.sh PSYS SRCDIR --generator       examples/cloth-small.json is exactly
#                                             what scripts/gen-cloth.sh writes
#   examples.sh PSYS SRCDIR --claims          the physics README/docs state
#   examples.sh PSYS SRCDIR --demo            scripts/demo.sh runs and writes its files
#   examples.sh PSYS SRCDIR --docs            every ```json block of README.md and
#                                             docs/*.md that is a whole scene (it has
#                                             a "psys" key) is one `psys check` accepts
set -euo pipefail

if [ $# -lt 3 ]; then
  echo "usage: examples.sh PSYS SRCDIR (EXAMPLE.json... | --all | --generator | --claims | --demo | --docs)" >&2
  exit 2
fi
psys=$(cd "$(dirname "$1")" && pwd)/$(basename "$1")
src=$(cd "$2" && pwd)
shift 2

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cd "$work"   # scenes name their own output files; keep them out of the tree

failures=0
fail() {
  echo "FAIL: $*" >&2
  failures=$((failures + 1))
}

# check_csv FILE HEADER: the header matches and every other field is a finite number.
check_csv() {
  local file=$1 header=$2
  if [ ! -s "$file" ]; then
    fail "$file is missing or empty"
    return
  fi
  if [ "$(head -n 1 "$file")" != "$header" ]; then
    fail "$file: header is '$(head -n 1 "$file")', expected '$header'"
    return
  fi
  local bad
  bad=$(awk -F, -v cols="$(awk -F, '{ print NF; exit }' <<<"$header")" '
    NR == 1 { next }
    NF != cols { print "line " NR ": " NF " fields"; exit }
    { for (k = 1; k <= NF; k++)
        if ($k !~ /^-?[0-9]+(\.[0-9]*)?(e[-+]?[0-9]+)?$/) { print "line " NR ": field " k " is " $k; exit } }
  ' "$file")
  [ -z "$bad" ] || fail "$file: not finite numbers: $bad"
}

# value KEY: the value of "KEY: value" in psys check output ($summary).
value() { awk -F': ' -v k="$1" '$1 == k { print $2 }' <<<"$summary"; }

test_example() {
  local ex=$1 name summary n dim header rows steps before=$failures
  name=$(basename "$ex" .json)
  if ! summary=$("$psys" check "$ex" 2>&1); then
    fail "$name: psys check failed: $summary"
    return
  fi
  n=$(value particles)
  dim=$(value dim)
  [[ "$n" =~ ^[1-9][0-9]*$ ]] || fail "$name: psys check reports particles '$n'"
  [[ "$(value energy)" =~ ^-?[0-9] ]] || fail "$name: psys check reports energy '$(value energy)'"
  if [ "$dim" = 2 ]; then header="step,t,i,x,y,vx,vy"; else header="step,t,i,x,y,z,vx,vy,vz"; fi
  rm -f "$name.csv" "$name-energy.csv"
  if ! "$psys" run "$ex" --steps 50 --every 10 --out "$name.csv" --energy "$name-energy.csv" --quiet; then
    fail "$name: psys run --steps 50 failed"
    return
  fi
  check_csv "$name.csv" "$header"
  check_csv "$name-energy.csv" "step,t,kinetic,potential,total"
  rows=$(($(wc -l <"$name.csv") - 1))
  if [ "$rows" -lt $((2 * n)) ] || [ $((rows % n)) -ne 0 ]; then
    fail "$name: $rows trajectory rows for $n particles"
  fi
  steps=$(tail -n 1 "$name-energy.csv" | cut -d, -f1)
  [ "$steps" = 50 ] || fail "$name: last frame is step $steps, expected 50"
  # The scene's own run (its settings and output names) must stay short and finite.
  if ! "$psys" run "$ex" --quiet; then
    fail "$name: psys run with the scene's own settings failed"
  fi
  [ "$failures" -ne "$before" ] || echo "ok: $name ($n particles, dim $dim)"
}

# near A B TOL WHAT
near() {
  awk -v a="$1" -v b="$2" -v tol="$3" 'BEGIN { d = a - b; if (d < 0) d = -d; exit !(d <= tol) }' \
    || fail "$4: got $1, expected $2 (tolerance $3)"
}

test_claims() {
  local ex=$src/examples
  # spring-oscillator: x(t) - r = A e^(-ζω0 t)(cos ωd t + ζ/√(1-ζ²) sin ωd t), period 2π/ωd.
  "$psys" run "$ex/spring-oscillator.json" --every 1 --out osc.csv --quiet
  local err period
  err=$(awk -F, 'NR > 1 && $3 == 1 {
      m = 1; k = 100; c = 0.5; A = 0.2; w0 = sqrt(k / m); z = c / (2 * sqrt(k * m)); wd = w0 * sqrt(1 - z * z)
      e = A * exp(-z * w0 * $2) * (cos(wd * $2) + z / sqrt(1 - z * z) * sin(wd * $2))
      d = $4 - 1 - e; if (d < 0) d = -d; if (d > max) max = d; if ($5 != 0) max = 1 }
    END { print max + 0 }' osc.csv)
  near "$err" 0 1e-8 "spring-oscillator: largest deviation from the closed form"
  period=$(awk -F, 'NR > 1 && $3 == 1 { u = $4 - 1
      if (have && pu < 0 && u >= 0) { tc = pt + ($2 - pt) * (-pu) / (u - pu); if (t0 == "") t0 = tc; else { t1 = tc; n++ } }
      pt = $2; pu = u; have = 1 }
    END { printf "%.9f", (t1 - t0) / n }' osc.csv)
  near "$period" 0.628514972 1e-6 "spring-oscillator: damped period"

  # hanging-chain: settles to the discrete catenary, middle particle 1.3611 m below the anchors.
  "$psys" run "$ex/hanging-chain.json" --out chain.csv --energy chain-e.csv --quiet
  local sag ke
  sag=$(awk -F, 'NR > 1 && $3 == 10 { y = $5 } END { print -y }' chain.csv)
  near "$sag" 1.3611 0.0005 "hanging-chain: sag of the middle particle"
  ke=$(tail -n 1 chain-e.csv | cut -d, -f3)
  near "$ke" 0 1e-5 "hanging-chain: kinetic energy at the end"

  # orbit-free-pair: total momentum (2, 0) and angular momentum kept to round-off;
  # verlet keeps the energy within 2e-5 J of 6.5 J (it oscillates, it does not drift).
  "$psys" run "$ex/orbit-free-pair.json" --out pair.csv --energy pair-e.csv --quiet
  local drift
  drift=$(awk -F, 'NR > 1 { m = ($3 == 0) ? 1 : 3; px[$1] += m * $6; py[$1] += m * $7; L[$1] += m * ($4 * $7 - $5 * $6) }
    END { for (s in px) { d = px[s] - 2; if (d < 0) d = -d; if (d > w) w = d
                          d = py[s]; if (d < 0) d = -d; if (d > w) w = d
                          d = L[s] - L[0]; if (d < 0) d = -d; if (d > w) w = d }
          print w + 0 }' pair.csv)
  near "$drift" 0 1e-12 "orbit-free-pair: momentum and angular momentum drift"
  drift=$(awk -F, 'NR > 1 { d = $5 - 6.5; if (d < 0) d = -d; if (d > w) w = d } END { print w + 0 }' pair-e.csv)
  near "$drift" 0 2e-5 "orbit-free-pair: energy drift"

  # lj-droplet: exactly opposite pair forces keep the total momentum (zero) to
  # round-off; velocity Verlet keeps the energy within 0.15 of -145.26 (the
  # force jumps at the cutoff; 0.090 measured); grid = direct bit for bit.
  "$psys" run "$ex/lj-droplet.json" --out lj.csv --energy lj-e.csv --quiet
  drift=$(awk -F, 'NR > 1 { px[$1] += $6; py[$1] += $7 }
    END { for (s in px) { d = px[s]; if (d < 0) d = -d; if (d > w) w = d
                          d = py[s]; if (d < 0) d = -d; if (d > w) w = d }
          print w + 0 }' lj.csv)
  near "$drift" 0 1e-12 "lj-droplet: total momentum"
  drift=$(awk -F, 'NR > 1 { d = $5 + 145.25897331910971; if (d < 0) d = -d; if (d > w) w = d } END { print w + 0 }' lj-e.csv)
  near "$drift" 0 0.15 "lj-droplet: energy drift"
  sed 's/"method": "grid", "skin": 0.3/"method": "direct"/' "$ex/lj-droplet.json" >lj-direct.json
  grep -q '"method": "direct"' lj-direct.json || fail "lj-droplet: no grid method to switch to direct"
  "$psys" run lj-direct.json --out lj-direct.csv --quiet
  cmp -s lj.csv lj-direct.csv || fail "lj-droplet: grid and direct trajectories differ"

  # projectile-drag: rk45 at tolerance 1e-9 follows the closed form of linear drag.
  "$psys" run "$ex/projectile-drag.json" --out ball.csv --quiet
  err=$(awk -F, 'NR > 1 { k = 0.25 / 0.5; vt = -9.81 / k; t = $2; q = 1 - exp(-k * t)
      x = 10 / k * q; y = vt * t + (10 - vt) / k * q; vy = vt + (10 - vt) * exp(-k * t)
      d = $4 - x; if (d < 0) d = -d; if (d > w) w = d
      d = $5 - y; if (d < 0) d = -d; if (d > w) w = d
      d = $8 - vy; if (d < 0) d = -d; if (d > w) w = d }
    END { print w + 0 }' ball.csv)
  near "$err" 0 1e-8 "projectile-drag: deviation from the closed form"
  # rk45 lands exactly on every output time: frames at multiples of every·dt = 0.05 s.
  local times
  times=$(awk -F, 'NR > 1 { printf "%s ", $2 }' ball.csv | cut -d' ' -f1-3,61)
  [ "$times" = "0 0.050000000000000003 0.10000000000000001 3" ] || fail "projectile-drag: frame times $times"

  # pendulum: a stiff spring of 1 m from a 90° start swings with the period of a
  # rigid pendulum at that amplitude, 2.37 s (the spring stretches slightly).
  "$psys" run "$ex/pendulum.json" --every 1 --out pend.csv --quiet
  period=$(awk -F, 'NR > 1 && $3 == 1 { u = $4
      if (have && pu < 0 && u >= 0) { tc = pt + ($2 - pt) * (-pu) / (u - pu); if (t0 == "") t0 = tc; else { t1 = tc; n++ } }
      pt = $2; pu = u; have = 1 }
    END { printf "%.4f", (t1 - t0) / n }' pend.csv)
  near "$period" 2.37 0.02 "pendulum: period"

  # bouncing-balls: restitution 0.8 makes each apex 0.64 of the one before
  # (1 m dropped: 0.64, 0.4096, 0.262144 m); the dropped ball is at rest on the
  # floor by t = 4.5 s (the bounces add up to 4.06 s); the thrown ball then
  # slides with v(t) ∝ exp(-k_f g t), k_f = 0.2; the ball dropped on the 30°
  # slope (friction k_f = 2) ends up sliding down it at the steady speed
  # tan 30° / k_f = 0.288675 m/s; no ball is ever behind a plane.
  "$psys" run "$ex/bouncing-balls.json" --every 1 --out balls.csv --quiet
  local apexes
  apexes=$(awk -F, 'NR > 1 && $3 == 0 { y = $5; if (c > 1 && py > ppy && py >= y && n < 3) { printf "%.5f ", py; n++ }
                                          ppy = py; py = y; c++ }' balls.csv)
  [ "$apexes" = "0.64000 0.40960 0.26214 " ] || fail "bouncing-balls: apex heights $apexes"
  local rest
  rest=$(awk -F, 'NR > 1 && $3 == 0 && $2 >= 4.5 && ($5 != 0 || $6 != 0 || $7 != 0) { n++ } END { print n + 0 }' balls.csv)
  [ "$rest" = 0 ] || fail "bouncing-balls: the dropped ball is not at rest after t = 4.5 s ($rest frames)"
  local ratio
  ratio=$(awk -F, 'NR > 1 && $3 == 1 && $2 == 4 { a = $6 } NR > 1 && $3 == 1 && $2 == 5 { b = $6 } END { print b / a }' balls.csv)
  near "$ratio" "$(awk 'BEGIN { print exp(-0.2 * 9.81 * 1) }')" 1e-3 "bouncing-balls: friction slow-down of the thrown ball over 1 s"
  local slide
  slide=$(awk -F, 'NR > 1 && $3 == 3 && $2 >= 3 && $2 <= 6 {
      d = -0.5 * ($4 - 1) + 0.86602540378443865 * $5; if (d > 1e-9 || d < -1e-9) off++
      e = sqrt($6 * $6 + $7 * $7) - sqrt(1 / 3) / 2; if (e < 0) e = -e; if (e > w) w = e }
    END { print (off ? 1 : w + 0) }' balls.csv)
  near "$slide" 0 1e-4 "bouncing-balls: the slider's speed on the slope differs from tan 30°/k_f (or it left the slope)"
  local behind
  behind=$(awk -F, 'NR > 1 && ($5 < 0 || $4 < -1 || -0.5 * ($4 - 1) + 0.86602540378443865 * $5 < -1e-9) { n++ } END { print n + 0 }' balls.csv)
  [ "$behind" = 0 ] || fail "bouncing-balls: $behind rows behind a plane"

  # double-pendulum: undamped stiff springs, so rk4 keeps the energy, 20.81 J,
  # within 1e-4 J; the motion is chaotic: moving the lower bob's start by
  # 1 µm changes nothing visible for the first second, yet puts it more than
  # 0.3 m away from the original run at some time between t = 8 and 10 s.
  "$psys" run "$ex/double-pendulum.json" --out dp.csv --energy dp-e.csv --quiet
  drift=$(awk -F, 'NR == 2 { e0 = $5 } NR > 1 { d = $5 - e0; if (d < 0) d = -d; if (d > w) w = d } END { print w + 0 }' dp-e.csv)
  near "$drift" 0 1e-4 "double-pendulum: energy drift"
  sed 's/"x": \[1.4142135623730951, 1.4142135623730951\]/"x": [1.4142135623730951, 1.4142145623730951]/' \
    "$ex/double-pendulum.json" > dp-nudged.json
  if cmp -s dp-nudged.json "$ex/double-pendulum.json"; then
    fail "double-pendulum: could not nudge the lower bob (its start changed?)"
  else
    "$psys" run dp-nudged.json --out dp2.csv --quiet
    local early late
    read -r early late < <(paste -d, dp.csv dp2.csv | awk -F, 'NR > 1 && $3 == 2 {
        d = sqrt(($4 - $11) ^ 2 + ($5 - $12) ^ 2)
        if ($2 <= 1 && d > e) e = d; if ($2 >= 8 && d > l) l = d }
      END { print e + 0, l + 0 }')
    near "$early" 0 1e-5 "double-pendulum: nudged run separated during the first second"
    awk -v l="$late" 'BEGIN { exit !(l > 0.3) }' || fail "double-pendulum: nudged run only $late m away at t = 8..10 s (not chaotic?)"
  fi

  # hanging-cloth: after 5 s the 20×20 sheet hangs still (kinetic energy below
  # 1e-3 J) from its two pinned corners, mirror-symmetric to round-off, its
  # bottom edge 0.981 m below the pins (0.95 m of cloth stretched by its
  # weight) and the middle of its top edge sagging 0.072 m between the pins.
  "$psys" run "$ex/hanging-cloth.json" --out cloth.csv --energy cloth-e.csv --quiet
  ke=$(tail -n 1 cloth-e.csv | cut -d, -f3)
  awk -v k="$ke" 'BEGIN { exit !(k < 1e-3) }' || fail "hanging-cloth: kinetic energy $ke J at the end"
  local bottom topmid asym
  read -r bottom topmid asym < <(awk -F, 'NR > 1 && $1 == 5000 { x[$3] = $4; y[$3] = $5 }
    END { for (j = 0; j < 20; j++) for (i = 0; i < 20; i++) { a = i + 20 * j; b = 19 - i + 20 * j
            d = x[a] + x[b] - 0.95; if (d < 0) d = -d; if (d > m) m = d
            d = y[a] - y[b]; if (d < 0) d = -d; if (d > m) m = d }
          print -y[390], -y[10], m + 0 }' cloth.csv)
  near "$bottom" 0.981 0.002 "hanging-cloth: depth of the bottom edge"
  near "$topmid" 0.072 0.002 "hanging-cloth: sag of the top edge"
  near "$asym" 0 1e-9 "hanging-cloth: departure from mirror symmetry"

  # rope-bridge: once settled, the two anchors together hold the weight of the
  # free rope and the crate, (19 · 0.5 + 5) kg · 9.81 = 142.245 N, and the
  # horizontal pull (51.7 N) is the same in every segment, crate or not.
  "$psys" run "$ex/rope-bridge.json" --out bridge.csv --quiet
  local vsum hmin hmax
  read -r vsum hmin hmax < <(awk -F, 'NR > 1 && $1 == 20000 { x[$3] = $4; y[$3] = $5 }
    END { n = 0; for (i = 1; i <= 11; i++) o[n++] = i; for (i = 21; i >= 12; i--) o[n++] = i
          hmin = 1e300; hmax = -1e300
          for (k = 0; k + 1 < n; k++) { dx = x[o[k + 1]] - x[o[k]]; dy = y[o[k + 1]] - y[o[k]]; l = sqrt(dx * dx + dy * dy)
            T = 20000 * (l - 0.25); h = T * dx / l; if (h < hmin) hmin = h; if (h > hmax) hmax = h
            if (k == 0) v0 = -T * dy / l; if (k + 2 == n) v1 = T * dy / l }
          print v0 + v1, hmin, hmax }' bridge.csv)
  near "$vsum" 142.245 0.2 "rope-bridge: vertical load on the anchors"
  near "$hmin" 51.7 0.2 "rope-bridge: smallest horizontal pull"
  near "$hmax" 51.7 0.2 "rope-bridge: largest horizontal pull"

  # motor-mechanism: the two pistons stay within 0.2 mm of their cylinders'
  # lines (±45° from vertical) and within 0.5 mm of the rigid crank–slider
  # position s = c·d + sqrt(L² − r² + (c·d)²), c the crank pin, r = 0.25 m,
  # L = 1 m, so each strokes between L − r and L + r.
  "$psys" run "$ex/motor-mechanism.json" --out motor.csv --quiet
  local off dev
  read -r off dev < <(awk -F, 'NR > 1 && $3 >= 2 { th = 6.283185307179586 * $2 + 1.5707963267948966
      cx = 0.25 * cos(th); cy = 0.25 * sin(th); h = sqrt(0.5); dx = ($3 == 2) ? -h : h; dy = h
      cd = cx * dx + cy * dy; s = cd + sqrt(1 - 0.0625 + cd * cd)
      o = $4 * dy - $5 * dx; if (o < 0) o = -o; if (o > mo) mo = o
      d = $4 * dx + $5 * dy - s; if (d < 0) d = -d; if (d > md) md = d }
    END { print mo + 0, md + 0 }' motor.csv)
  near "$off" 0 2e-4 "motor-mechanism: piston off its line"
  near "$dev" 0 5e-4 "motor-mechanism: piston off the rigid crank-slider position"

  # worm: with backward_friction 30 against forward 0.3 the muscle wave makes
  # the worm crawl +x at 0.420 m/s (centre of mass, whole muscle cycles from
  # the 2nd to the 12th), never leaving the floor; with the same friction
  # both ways it only pulses in place.
  "$psys" run "$ex/worm.json" --every 1 --out worm.csv --quiet
  local speed lifted
  read -r speed lifted < <(awk -F, 'NR > 1 { sx[$1] += $4; if ($5 != 0) up++ }
    END { T = 2 * 3.141592653589793 / 8; a = int(2 * T * 1000 + 0.5); b = int(12 * T * 1000 + 0.5)
          print (sx[b] - sx[a]) / 11 / (10 * T), up + 0 }' worm.csv)
  near "$speed" 0.420 0.005 "worm: crawling speed"
  [ "$lifted" = 0 ] || fail "worm: $lifted rows off the floor"
  grep -v '"forward"' "$ex/worm.json" | sed 's/"friction": 0.3,$/"friction": 0.3}/' > worm-iso.json
  "$psys" run worm-iso.json --every 1000 --out worm-iso.csv --quiet
  speed=$(awk -F, 'NR > 1 { sx[$1] += $4 } END { print (sx[10000] - sx[0]) / 11 / 10 }' worm-iso.csv)
  near "$speed" 0 0.005 "worm: speed with the same friction in every direction"

  # soft-block: dropped tilted, it bounces, tumbles and settles flat: after
  # 4 s its 25 bottom particles rest exactly on the floor, its top face is at
  # 0.2992 m (0.3 m less 0.8 mm squashed by its weight), nothing is moving
  # (kinetic energy below 1e-9 J) and no particle was ever below the floor.
  "$psys" run "$ex/soft-block.json" --out block.csv --energy block-e.csv --quiet
  local onfloor top below
  read -r onfloor top below < <(awk -F, 'NR > 1 { if ($5 < 0) below++ }
    NR > 1 && $1 == 4000 { if ($5 == 0) n++; if ($5 > top) top = $5 }
    END { print n + 0, top + 0, below + 0 }' block.csv)
  [ "$onfloor" = 25 ] || fail "soft-block: $onfloor particles on the floor at the end, expected 25"
  near "$top" 0.2992 0.0002 "soft-block: height of the top face"
  [ "$below" = 0 ] || fail "soft-block: $below rows below the floor"
  ke=$(tail -n 1 block-e.csv | cut -d, -f3)
  near "$ke" 0 1e-9 "soft-block: kinetic energy at the end"

  # wheel: on the 15° non-slip slope the hub gains speed at 1.23 m/s², 95% of
  # the 1.295 m/s² of an ideal rolling rim and hub (g sin 15° · 25/49); on the
  # floor it rolls at about 3 m/s without slipping (ωR = hub speed within 3%).
  "$psys" run "$ex/wheel.json" --every 20 --out wheel.csv --quiet
  local accel slip
  read -r accel slip < <(awk -F, 'NR > 1 { x[$1, $3] = $4; y[$1, $3] = $5; vx[$1, $3] = $6; vy[$1, $3] = $7 }
    END { sa = vx[1000, 24] * 0.9659258262890683 - vy[1000, 24] * 0.25881904510252074
          sb = vx[4000, 24] * 0.9659258262890683 - vy[4000, 24] * 0.25881904510252074
          s = 7000; w = 0
          for (i = 0; i < 24; i++) { dx = x[s, i] - x[s, 24]; dy = y[s, i] - y[s, 24]
            w += (dx * (vy[s, i] - vy[s, 24]) - dy * (vx[s, i] - vx[s, 24])) / (dx * dx + dy * dy) }
          w /= 24; v = sqrt(vx[s, 24] ^ 2 + vy[s, 24] ^ 2)
          print (sb - sa) / 1.5, -w * 0.3 / v - 1 }' wheel.csv)
  near "$accel" 1.23 0.03 "wheel: acceleration down the slope"
  near "$slip" 0 0.03 "wheel: rolling without slipping on the floor (ωR/v - 1)"

  # driven-pendulum: the controlled pivot is exactly on x = 0.05 sin 3t with the
  # exact velocity 0.15 cos 3t at every frame (controllers are not integrated).
  "$psys" run "$ex/driven-pendulum.json" --out driven.csv --quiet
  err=$(awk -F, 'NR > 1 && $3 == 0 { d = $4 - 0.05 * sin(3 * $2); if (d < 0) d = -d; if (d > w) w = d
                                     d = $6 - 0.15 * cos(3 * $2); if (d < 0) d = -d; if (d > w) w = d
                                     if ($5 != 0 || $7 != 0) w = 1 }
                 END { print w + 0 }' driven.csv)
  near "$err" 0 1e-12 "driven-pendulum: pivot off its prescribed path"
  [ "$failures" -ne 0 ] || echo "ok: claims"
}

case "$1" in
  --all)
    shopt -s nullglob
    examples=("$src"/examples/*.json)
    [ ${#examples[@]} -gt 0 ] || fail "no examples/*.json"
    for ex in "${examples[@]}"; do test_example "$ex"; done
    ;;
  --generator)
    if ! bash "$src/scripts/gen-cloth.sh" | cmp -s - "$src/examples/cloth-small.json"; then
      fail "examples/cloth-small.json differs from scripts/gen-cloth.sh output (regenerate: scripts/gen-cloth.sh > examples/cloth-small.json)"
    else
      echo "ok: examples/cloth-small.json matches scripts/gen-cloth.sh"
    fi
    ;;
  --claims)
    test_claims
    ;;
  --demo)
    out=$(bash "$src/scripts/demo.sh" "$psys" demo-out) || fail "scripts/demo.sh failed"
    echo "$out"
    check_csv demo-out/cloth.csv "step,t,i,x,y,z,vx,vy,vz"
    check_csv demo-out/cloth-energy.csv "step,t,kinetic,potential,total"
    grep -q '^run: .* 151 frames written' <<<"$out" || fail "demo summary does not report 151 frames"
    [ -s demo-out/cloth-energy.png ] || fail "scripts/demo.sh did not write demo-out/cloth-energy.png"
    if command -v ffmpeg >/dev/null 2>&1; then video=demo-out/cloth.mp4; else video=demo-out/cloth.gif; fi
    [ -s "$video" ] || fail "scripts/demo.sh did not write $video"
    if [ "$video" = demo-out/cloth.mp4 ] && command -v ffprobe >/dev/null 2>&1; then
      frames=$(ffprobe -v error -count_frames -select_streams v:0 -show_entries stream=nb_read_frames -of csv=p=0 "$video")
      [ "$frames" = 91 ] || fail "demo video has $frames frames, expected 91 (3 s at 30 fps)"
    fi
    ;;
  --docs)
    count=0
    for doc in "$src"/README.md "$src"/docs/*.md; do
      [ -f "$doc" ] || continue
      base=$(basename "$doc" .md)
      awk -v out="$base" '/^```json[ \t]*$/ { n++; f = out "-" n ".json"; inb = 1; next }
                          /^```/ { inb = 0; next }
                          inb { print > f }' "$doc"
    done
    for snippet in *.json; do
      [ -f "$snippet" ] || continue
      grep -q '"psys"' "$snippet" || continue   # a fragment (one force, one structure)
      count=$((count + 1))
      msg=$("$psys" check "$snippet" 2>&1 >/dev/null) || fail "json snippet $snippet (file-block number) is not a valid scene: $msg"
    done
    [ "$count" -gt 0 ] || fail "no json snippets found in README.md and docs/"
    [ "$failures" -ne 0 ] || echo "ok: $count json snippets in README.md and docs/ are valid scenes"
    ;;
  *)
    for ex in "$@"; do test_example "$ex"; done
    ;;
esac

if [ "$failures" -ne 0 ]; then
  echo "$failures failure(s)" >&2
  exit 1
fi
