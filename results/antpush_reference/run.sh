#!/usr/bin/env bash
# The side-by-side study's runs (README.md, "The runs"), from the pinned commit in a git worktree,
# at the lowest priority, each resumed from its newest checkpoint when it has one.
#
# From the main checkout, bash results/antpush_reference/run.sh and:
#   setup          the worktree and the reference venv (once a machine)
#   queue          everything left, in the protocol's order, in the background
#   ours | hiro    one of ours (in the foreground)
#   ref S          the code's seed S (in the foreground)
#   status         what runs, how far each run is, here and committed
#   sync [note]    the runs' rows and logs into this checkout, one commit
#
# The queue has two lanes, one a core: ours then HIRO; the code's seeds 0, 1, 2 one after the
# other (a finished run is skipped). Run this copy (main's), from the project's venv (python on
# PATH). Settings: STUDY_TREE (the worktree, default ../study2 beside this checkout),
# REFERENCE_HOME (the reference venv and code, as reference.setup takes it), STUDY_MIRROR (a
# local git directory of the upstream code, for setup).
set -euo pipefail

PIN=9d0c539                      # the runs' commit from 2026-12-06 evening (README.md, "Changes")
MAIN=$(cd "$(dirname "$0")/../.." && pwd)
TREE=${STUDY_TREE:-$(dirname "$MAIN")/study2}
FOLDER=results/antpush_reference
LOGS="$TREE/$FOLDER/logs"
MIRROR=${STUDY_MIRROR:-}         # reference.setup --from-mirror

ours_command() {  # $1: ours or hiro
  echo python -m experiments.antpush --method "$1" --preset paper --physics c \
    --contacts mujoco200 --steps 1100000 --seeds 6 --seed 0 --checkpoint-every 10000 \
    --eval_extra held --no-progress --out "$FOLDER/$1"
}

ref_command() {  # $1: the seed
  echo python -m reference.run --seed "$1" --steps 1110000 --eval batched-td3 \
    --physics mujoco200 --out "$FOLDER/reference/seed$1"
}

lowest_priority() {  # this shell's autogroup at nice 19 (what `nice` alone leaves at 0)
  echo 19 > /proc/self/autogroup 2>/dev/null || true
}

has_row() {  # $1: a csv, $2: a column, $3: a value
  [ -f "$1" ] && awk -F, -v c="$2" -v v="$3" \
    'NR > 1 && $c == v { found = 1 } END { exit !found }' "$1"
}
# Done: the run's last evaluation is in its rows, in the worktree or committed here (a run whose
# rows are all committed is not run again on a new machine, whose worktree starts empty).
ours_done() {
  has_row "$TREE/$FOLDER/$1/metrics.csv" 4 1100000 \
    || has_row "$MAIN/$FOLDER/$1/metrics.csv" 4 1100000
}
ref_done() {
  local rows="$FOLDER/reference/seed$1/evaluations.csv"
  [ -f "$TREE/$FOLDER/reference/seed$1/done.json" ] || has_row "$MAIN/$rows" 1 1100000
}

run_ours() {  # start, or resume the run's folder
  local method=$1 out="$TREE/$FOLDER/$1"
  if ours_done "$method"; then echo "$method: done"; return 0; fi
  mkdir -p "$LOGS"; lowest_priority; cd "$TREE"
  if [ -f "$out/config.json" ]; then
    PYTHONPATH="$TREE" nice -n 19 python -m experiments.antpush --resume "$FOLDER/$method" \
      --no-progress >> "$LOGS/$method.log" 2>&1
  else
    PYTHONPATH="$TREE" nice -n 19 $(ours_command "$method") >> "$LOGS/$method.log" 2>&1
  fi
}

run_ref() {  # the same command starts and resumes
  local seed=$1
  if ref_done "$seed"; then echo "the code's seed $seed: done"; return 0; fi
  mkdir -p "$LOGS"; lowest_priority; cd "$TREE"
  PYTHONPATH="$TREE" nice -n 19 $(ref_command "$seed") >> "$LOGS/ref$seed.log" 2>&1
}

setup() {
  if [ ! -d "$TREE" ]; then git -C "$MAIN" worktree add --detach "$TREE" "$PIN"; fi
  if [ "$(git -C "$TREE" rev-parse --short=7 HEAD)" != "$PIN" ]; then
    echo "$TREE is not at $PIN" >&2; exit 1
  fi
  cd "$TREE"
  if [ -n "$MIRROR" ]; then python -m reference.setup --from-mirror "$MIRROR"
  else python -m reference.setup; fi
}

queue() {  # two lanes, each in its own session (its own autogroup), detached from this shell
  if pgrep -f "run.sh lane-" > /dev/null; then
    echo "the queue runs already (bash $0 status)" >&2; exit 1
  fi
  setsid nohup bash "$0" lane-ours > /dev/null 2>&1 < /dev/null &
  setsid nohup bash "$0" lane-ref > /dev/null 2>&1 < /dev/null &
  echo "queued; logs in $LOGS"
}

newest() {  # $1: a csv, $2: the step's column. The largest step in its rows, or "-"
  [ -f "$1" ] && awk -F, -v c="$2" \
    'NR > 1 && $c + 0 > m { m = $c + 0 } END { print (m ? m : "-") }' "$1" || echo -
}

status() {
  pgrep -af "python -m (experiments.antpush|reference.harness)" || echo "no run is running"
  local m s
  for m in ours hiro; do
    echo "$m: rows to env step $(newest "$TREE/$FOLDER/$m/metrics.csv" 4) here," \
      "$(newest "$MAIN/$FOLDER/$m/metrics.csv" 4) committed$(ours_done "$m" && echo '; done')"
  done
  for s in 0 1 2; do
    local rows="$FOLDER/reference/seed$s/evaluations.csv"
    echo "the code's seed $s: rows to t = $(newest "$TREE/$rows" 1) here," \
      "$(newest "$MAIN/$rows" 1) committed$(ref_done "$s" && echo '; done')"
  done
}

TIMING=""  # the columns that measure time (reference.logs.TIMING), set by sync_rows

determined() {  # $1: a csv, $2: how many lines. Those lines, their timing columns emptied
  head -n "$2" "$1" | awk -F, -v OFS=, -v drop="$TIMING" '
    { sub(/\r$/, "") }  # the csv module ends lines with \r\n
    NR == 1 { n = split(drop, d, " ")
              for (i = 1; i <= NF; i++) for (j = 1; j <= n; j++) if ($i == d[j]) t[i] = 1 }
    NR > 1 { for (i in t) $i = "" } { print }'
}

sync_rows_file() {  # $1: a csv under $FOLDER. Copied when its rows extend the committed ones,
  # times aside (a resumed reference run writes its checkpoint's evaluation row again, with
  # its own times). A restart of the same seeds from step 0 on a machine with another CPU
  # differs, and is refused; on the same CPU model it repeats the committed rows bit for bit
  # (HIRO's, 2026-12-07: README.md, "Changes"), and is taken.
  local new="$TREE/$1" old="$MAIN/$1" n
  [ -f "$new" ] || return 0
  n=$(wc -l < "$new")
  if [ -f "$old" ]; then
    if ! cmp -s <(determined "$old" "$n") <(determined "$new" "$(wc -l < "$old")"); then
      echo "$1: the run's rows differ from the committed ones (the first below); not copied" >&2
      diff <(determined "$old" "$n") <(determined "$new" "$(wc -l < "$old")") | head -n 4 >&2
      return 1
    fi
    [ "$n" -gt "$(wc -l < "$old")" ] || return 0
  fi
  mkdir -p "$(dirname "$old")"
  head -n "$n" "$new" > "$old"; git -C "$MAIN" add "$1"   # whole lines (one may be being written)
}

copy_changed() {  # $1: a file, $2: its path under this checkout. Copied and staged if it differs
  [ -f "$1" ] || return 0
  cmp -s "$1" "$MAIN/$2" 2>/dev/null && return 0
  cp "$1" "$MAIN/$2"; git -C "$MAIN" add "$2"
}

sync_run() {  # $1: a run's folder under $FOLDER, then its row files, then "--", its other files
  # (config.json, provenance.json: copied as they are when every row file was taken)
  local dir=$1 f; shift
  while [ "$1" != -- ]; do sync_rows_file "$FOLDER/$dir/$1" || return 1; shift; done
  shift
  for f in "$@"; do copy_changed "$TREE/$FOLDER/$dir/$f" "$FOLDER/$dir/$f"; done
}

sync_log() {  # $1: a lane's log (logs/<name>.log in the worktree), $2: the run's folder.
  # The committed run.log, extended by the lane's. A lane's log that does not begin with the
  # committed one (the run started again from step 0 on a new machine, its rows taken) is
  # joined to it first, after a line that says so, in place (the run appends to that file).
  local log="$LOGS/$1.log" old="$MAIN/$FOLDER/$2/run.log"
  [ -d "$MAIN/$FOLDER/$2" ] && [ -f "$log" ] || return 0
  if [ -f "$old" ] && ! cmp -s "$old" <(head -c "$(wc -c < "$old")" "$log"); then
    { cat "$old"
      echo "# run.sh sync, $(date -u '+%Y-%m-%d %H:%M UTC'): the lines above are the committed" \
        "log; the run started again, and its log goes on below"
      cat "$log"; } > "$log.joined"
    cat "$log.joined" > "$log" && rm "$log.joined"
  fi
  copy_changed "$log" "$FOLDER/$2/run.log"
}

extents() {  # how far each run's committed rows go, for the commit's message
  local m s parts=()
  for m in ours hiro; do
    [ -f "$MAIN/$FOLDER/$m/metrics.csv" ] \
      && parts+=("$m env step $(newest "$MAIN/$FOLDER/$m/metrics.csv" 4)")
  done
  for s in 0 1 2; do
    [ -f "$MAIN/$FOLDER/reference/seed$s/evaluations.csv" ] && parts+=(
      "the code's seed $s t = $(newest "$MAIN/$FOLDER/reference/seed$s/evaluations.csv" 1)")
  done
  local IFS=,; echo "${parts[*]}" | sed 's/,/, /g'
}

sync_rows() {  # $1: a note for the commit's message (optional)
  local status=0 m s
  TIMING=$(python -c 'from reference.logs import TIMING; print(*TIMING)')
  for m in ours hiro; do
    sync_run "$m" metrics.csv -- config.json && sync_log "$m" "$m" || status=1
  done
  for s in 0 1 2; do
    sync_run "reference/seed$s" evaluations.csv windows.csv -- config.json provenance.json \
      && sync_log "ref$s" "reference/seed$s" || status=1
  done
  if ! git -C "$MAIN" diff --cached --quiet; then
    git -C "$MAIN" commit -q -m "$FOLDER: rows to $(extents)${1:+ ($1)}" \
      && git -C "$MAIN" log --oneline -1
  else
    echo "no new rows"
  fi
  return $status
}

# One block, read whole before it runs: the lanes run for hours from this file, which a later
# commit may change under them (bash reads a script as it goes).
{
case "${1:-}" in
  setup) setup ;;
  queue) queue ;;
  status) status ;;
  ours|hiro) run_ours "$1" ;;
  ref) run_ref "${2:?the seed}" ;;
  lane-ours) run_ours ours && ours_done ours && run_ours hiro ;;
  lane-ref) for s in 0 1 2; do run_ref "$s" && ref_done "$s" || exit 1; done ;;
  sync) sync_rows "${2:-}" ;;
  *) awk 'NR > 1 && /^#/ { print; next } NR > 1 { exit }' "$0"; exit 2 ;;
esac
exit $?
}
