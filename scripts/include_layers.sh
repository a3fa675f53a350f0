#!/usr/bin/env bash
# The library's folders in layers, lowest first: a header may include headers
# of its own folder and of lower layers only, the library never includes the
# pipeline (examples/pipeline/, above every library layer), and a header longer
# than 500 lines says why in a comment starting "Length:". Prints the include
# graph (folder -> folders it includes) and exits 1 on any violation.
#
#   bash scripts/include_layers.sh
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
layers=(core ad optics optim geometry scene accel io metrics render losses cuda pipeline)
rank() {
  local i
  for i in "${!layers[@]}"; do [ "${layers[$i]}" = "$1" ] && { echo "$i"; return; }; done
  echo -1
}
status=0
declare -A graph
headers=$(cd "$root" && ls include/difftrans/*/*.hpp include/difftrans/*/*.cuh examples/pipeline/*.hpp 2>/dev/null)
for h in $headers; do
  case $h in
    examples/pipeline/*) from=pipeline ;;
    *) from=$(basename "$(dirname "$h")") ;;
  esac
  rf=$(rank "$from")
  if [ "$rf" -lt 0 ]; then echo "include_layers: $h: folder '$from' has no layer (add it to scripts/include_layers.sh)"; status=1; continue; fi
  while IFS=: read -r line target; do
    case $target in
      pipeline/*) to=pipeline ;;
      difftrans/*/*) to=${target#difftrans/}; to=${to%%/*} ;;
      *) continue ;;
    esac
    rt=$(rank "$to")
    [ "$to" = "$from" ] || graph[$from]="${graph[$from]:-} $to"
    if [ "$rt" -lt 0 ] || [ "$rt" -gt "$rf" ]; then
      echo "include_layers: $h:$line includes $target: '$to' is not below '$from'"
      status=1
    fi
  done < <(grep -n '^#include "' "$root/$h" | sed 's/^\([0-9]*\):#include "\([^"]*\)".*/\1:\2/')
  n=$(wc -l < "$root/$h")
  if [ "$n" -gt 500 ] && ! head -40 "$root/$h" | grep -q '^// Length:'; then
    echo "include_layers: $h has $n lines and no '// Length:' comment saying why"
    status=1
  fi
done
for l in "${layers[@]}"; do
  printf '%-9s -> %s\n' "$l" "$(echo ${graph[$l]:-} | tr ' ' '\n' | sort -u | tr '\n' ' ')"
done
exit $status
