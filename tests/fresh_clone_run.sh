#!/usr/bin/env bash
# One fresh-clone run of the README's test command, as issue 31 counts them:
#
#   tests/fresh_clone_run.sh NAME [BURNERS] [pytest args...]
#
# clones this repository's HEAD (what is committed, nothing else) beside it as
# ../fresh-clone-NAME (or into $FRESH_CLONE_PARENT), so its ../shared is this checkout's; starts BURNERS busy loops (0) as a
# loaded CI box has; runs launch_scripts/run_tests.sh there with a JUnit report whose suite
# name says what ran beside it; and appends a line to out/fresh-clones/summary.txt.  The log
# and the report go to out/fresh-clones/NAME.{log,xml}; `tests/flake_hunt.py --junit
# out/fresh-clones/*.xml` counts each test's runs and failures over them.  The clone is removed
# when the run passed and kept (with its out/failed/) when it did not.  Runs one at a time:
# two at once would share two cores and measure neither.
set -uo pipefail
if [[ $# -lt 1 || $1 == -* ]]; then
  echo "usage: tests/fresh_clone_run.sh NAME [BURNERS] [pytest args...]" >&2; exit 2
fi
name=$1; shift
burners=0
if [[ $# -gt 0 && $1 =~ ^[0-9]+$ ]]; then burners=$1; shift; fi
repo=$(cd "$(dirname "$0")/.." && pwd)
# FRESH_CLONE_PARENT: clone into that folder instead (e.g. a mode-700 one made by mktemp -d,
# as root's home is), with ../shared linked beside the clone
parent=${FRESH_CLONE_PARENT:-$(dirname "$repo")}
if [[ ! -e $parent/shared ]]; then ln -s "$(dirname "$repo")/shared" "$parent/shared" || exit 2; fi
clone=$parent/fresh-clone-$name
records=$repo/out/fresh-clones
mkdir -p "$records"
if [[ -e $clone ]]; then echo "fresh_clone_run: $clone is there already" >&2; exit 2; fi
git clone -q "$repo" "$clone" || exit 2
pids=()
stop_burners() { for pid in "${pids[@]}"; do kill "$pid" 2>/dev/null; done; }
trap stop_burners EXIT
for ((i = 0; i < burners; i++)); do python3 -c 'while True: pass' & pids+=($!); done
echo "[fresh_clone_run] $name: $(git -C "$clone" rev-parse --short HEAD) in $clone," \
     "$burners burner(s); log in $records/$name.log"
start=$(date +%s)
(cd "$clone" && launch_scripts/run_tests.sh -o "junit_suite_name=burners=$burners" \
   --junitxml="$records/$name.xml" "$@") > "$records/$name.log" 2>&1
rc=$?
end=$(date +%s)
stop_burners
line="$name $(git -C "$clone" rev-parse --short HEAD) burners=$burners rc=$rc"
line+=" wall=$((end - start))s $(tail -1 "$records/$name.log")"
echo "$line" | tee -a "$records/summary.txt"
if [[ $rc -eq 0 ]]; then rm -rf "$clone"; else echo "[fresh_clone_run] kept $clone"; fi
exit $rc
