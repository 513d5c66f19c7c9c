#!/usr/bin/env bash
# Fetches the test scenes the real-scene tests and benchmarks read, from their public sources, into a folder:
#
#   scripts/fetch-scenes.sh [DEST]            (default ../shared/scenes, where the tests look; or set BVHC_SCENES)
#
# Each file of scripts/scenes.tsv is downloaded (curl), taken out of its archive where the source names a member
# (`URL!member` of a .zip or .tar.gz; an archive is downloaded once), gzipped where the path ends in .gz, and
# kept only if its SHA-256 (of the content: after gunzip for a .gz) is the one listed, the bytes the tests were
# written against. A file already in DEST with that hash is left alone. Files with no known public source
# (derived for these tests: the kitchen merged into one OBJ, decimated scans) and files whose source no longer
# serves the listed bytes are reported; the tests that need them report SKIPPED.
#
# BVHC_SCENES_SOURCE=URL fetches every file as URL/PATH instead (a mirror, or file:///path/to/a/copy, as CI
# tests this script). The scenes' licenses differ (../shared/scenes/README.md lists them): they are test data
# for this project; do not copy them into the repository.
set -euo pipefail
cd "$(dirname "$0")/.."

dest="${1:-${BVHC_SCENES:-../shared/scenes}}"
mirror="${BVHC_SCENES_SOURCE:-}"
manifest=scripts/scenes.tsv
for tool in curl sha256sum gzip; do
  command -v "$tool" >/dev/null 2>&1 || { echo "fetch-scenes: needs $tool" >&2; exit 2; }
done
mkdir -p "$dest"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

# The SHA-256 of a file's content (after gunzip when its path ends in .gz, not .tar.gz).
content_hash() {
  case "$2" in
    *.tar.gz) sha256sum < "$1" ;;
    *.gz) gzip -dc < "$1" | sha256sum ;;
    *) sha256sum < "$1" ;;
  esac | cut -d' ' -f1
}

# Downloads URL to FILE (once per URL for archives).
download() {
  curl --fail --silent --show-error --location --retry 2 --output "$2" "$1"
}

fetched=0 present=0 failed=0 unknown=0
failures=""
while IFS=$'\t' read -r path hash source; do
  case "$path" in ''|'#'*) continue ;; esac
  target="$dest/$path"
  if [ -f "$target" ] && [ "$(content_hash "$target" "$path")" = "$hash" ]; then
    present=$((present + 1))
    continue
  fi
  if [ -n "$mirror" ]; then
    source="$mirror/$path"
    member=""
  elif [ "$source" = "-" ]; then
    unknown=$((unknown + 1))
    failures="$failures\n  $path: no public source known (derived for these tests)"
    continue
  else
    member="${source#*!}"
    [ "$member" = "$source" ] && member=""
    source="${source%%!*}"
  fi
  part="$work/part"
  if [ -n "$member" ]; then
    archive="$work/archive-$(printf '%s' "$source" | sha256sum | cut -c1-16)"
    if [ ! -f "$archive" ] && ! download "$source" "$archive" 2>"$work/error"; then
      failed=$((failed + 1))
      failures="$failures\n  $path: $source: $(tr '\n' ' ' < "$work/error")"
      continue
    fi
    case "$source" in
      *.zip) command -v unzip >/dev/null && unzip -p "$archive" "$member" > "$part" 2>"$work/error" ;;
      *) tar -xzOf "$archive" "$member" > "$part" 2>"$work/error" ;;
    esac || { failed=$((failed + 1)); failures="$failures\n  $path: $member not in $source"; continue; }
    case "$path" in *.gz) gzip -n -9 < "$part" > "$part.gz" && mv "$part.gz" "$part" ;; esac
  elif ! download "$source" "$part" 2>"$work/error"; then
    failed=$((failed + 1))
    failures="$failures\n  $path: $source: $(tr '\n' ' ' < "$work/error")"
    continue
  fi
  got=$(content_hash "$part" "$path")
  if [ "$got" != "$hash" ]; then
    failed=$((failed + 1))
    failures="$failures\n  $path: $source serves other bytes (SHA-256 $got, expected $hash)"
    continue
  fi
  mkdir -p "$(dirname "$target")"
  mv "$part" "$target"
  fetched=$((fetched + 1))
done < "$manifest"

echo "fetch-scenes: $fetched fetched, $present already there, $failed failed, $unknown without a public source (into $dest)"
if [ -n "$failures" ]; then
  printf "not fetched:%b\n" "$failures"
fi
[ "$failed" = 0 ]
