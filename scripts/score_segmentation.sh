#!/usr/bin/env bash
# Scores `zonemap zones segment` on every floor plan of ../shared/data/floorplans against its
# ground truth and prints a markdown table (per map, the mean, and the published numbers).
# Usage: scripts/score_segmentation.sh [ZONEMAP_BINARY] [FLOORPLAN_DIR] [OUT_DIR]
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
zonemap="${1:-$here/build/seg-rel/app/zonemap}"
plans="${2:-$here/../shared/data/floorplans}"
out="${3:-$(mktemp -d)}"
[[ -x "$zonemap" ]] || { echo "score_segmentation: $zonemap is not an executable" >&2; exit 1; }
mkdir -p "$out"
echo "| map | GT rooms | zones | precision % | recall % | mean IoU % | IoU all cells % | runtime ms |"
echo "|---|---:|---:|---:|---:|---:|---:|---:|"
sum_p=0; sum_r=0; sum_i=0; sum_f=0; n=0
for map in "$plans"/*_map.png; do
  name="$(basename "$map" _map.png)"
  json="$("$zonemap" zones segment "$map" --score "$plans/${name}_gt.png" \
          --out "$out/$name.geojson" --json)"
  read -r p r i f g s ms < <(python3 -c '
import json, sys
j = json.load(sys.stdin); s = j["score"]
print(100 * s["precision"], 100 * s["recall"], 100 * s["mean_iou"], 100 * s["mean_iou_full"],
      s["gt_rooms"],
      j["zones"], j["segment_ms"])' <<<"$json")
  printf '| %s | %d | %d | %.1f | %.1f | %.1f | %.1f | %.0f |\n' "$name" "$g" "$s" "$p" "$r" "$i" "$f" \
    "$ms"
  sum_p=$(python3 -c "print($sum_p + $p)"); sum_r=$(python3 -c "print($sum_r + $r)")
  sum_i=$(python3 -c "print($sum_i + $i)"); sum_f=$(python3 -c "print($sum_f + $f)"); n=$((n + 1))
done
python3 -c "print('| **zonemap mean** | | | **%.1f** | **%.1f** | **%.1f** | **%.1f** | |' % ($sum_p / $n, $sum_r / $n, $sum_i / $n, $sum_f / $n))"
echo "| ROSE² (published) | | | 89.0 | 93.9 | 73.3 | | |"
echo "| ipa morphological (published) | | | 85.0 | 82.3 | 51.2 | | |"
echo "| ipa distance transform (published) | | | 88.3 | 79.8 | 54.7 | | |"
echo "| ipa Voronoi (published) | | | 85.9 | 71.9 | 28.7 | | |"
