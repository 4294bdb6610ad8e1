#!/usr/bin/env bash
# Writes a program's manual page (roff, gzip -9n) from its --help text, so
# that the page says what the program says: used by the build for every
# program the packages install (cmake/CncPackaging.cmake).
#   man_from_help.sh NAME "ONE-LINE SUMMARY" OUTPUT.1.gz PROGRAM [ARG...]
# PROGRAM ARG... --help is run; its stdout and stderr are the page's body.
set -euo pipefail
[ $# -ge 4 ] || { echo "usage: man_from_help.sh NAME SUMMARY OUTPUT.1.gz PROGRAM [ARG...]" >&2; exit 2; }
name="$1" summary="$2" out="$3"
shift 3
help="$("$@" --help 2>&1 || true)"
if [ -z "$help" ]; then
  echo "man_from_help.sh: $* --help printed nothing" >&2
  exit 1
fi
tmp="$(mktemp)"
trap 'rm -f "$tmp"' EXIT
upper="$(echo "$name" | tr '[:lower:]' '[:upper:]')"
{
  echo ".TH $upper 1 \"\" \"cnc\" \"CNC controller\""
  echo ".SH NAME"
  echo "$name \\- $summary"
  echo ".SH DESCRIPTION"
  echo ".nf"
  # roff: a backslash is written \e; a line starting with . or ' is protected by \&.
  printf '%s\n' "$help" | sed -e 's/\\/\\e/g' -e "s/^\([.']\)/\\\\\&\1/"
  echo ".fi"
  echo ".SH SEE ALSO"
  echo "The documentation in /usr/share/doc/cnc-configs/ (README.md, docs/*.md),"
  echo "the sample configurations in /usr/share/cnc/configs/ and"
  echo ".BR cnc-config (1)."
} >"$tmp"
gzip -9n -c "$tmp" >"$out"
