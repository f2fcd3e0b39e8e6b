#!/usr/bin/env bash
# Bad input to `relight compile` ends in exit status 1 with a message: never a
# crash, a hang or a sanitizer report.
source "$(dirname "$0")/lib.sh"

# check_rejected DESCRIPTION FILE: exit 1, some message on stderr, no crash.
check_rejected() {
	run "$1" "$relight" compile --emit report "$2"
	expect_no_crash
	expect_status 1
	expect_empty_stdout
	checks=$((checks + 1))
	[ -s "$work/stderr" ] || fail "no message on stderr"
}

run "missing file" "$relight" compile "$work/nonexistent.sl"
expect_no_crash
expect_status 1
expect_stderr "cannot open '$work/nonexistent.sl': No such file or directory"

run "missing bare name" env RELIGHT_SHADER_PATH="$work" "$relight" compile nosuchshader.sl
expect_status 1
expect_stderr "cannot open 'nosuchshader.sl'"

run "a directory" "$relight" compile "$work"
expect_status 1
expect_stderr "is a directory"

: >"$work/empty.sl"
check_rejected "empty file" "$work/empty.sl"

printf '/* only a comment */\n' >"$work/comment.sl"
check_rejected "only a comment" "$work/comment.sl"

# Deterministic garbage, so a failure can be reproduced.
python3 -c '
import random, sys
r = random.Random(20240611)
sys.stdout.buffer.write(bytes(r.randrange(256) for _ in range(65536)))
' >"$work/garbage.sl"
check_rejected "64 KiB of binary garbage" "$work/garbage.sl"

printf 'surface s() { Ci = 1; }\0surface t() {}\n' >"$work/nul.sl"
check_rejected "a NUL byte" "$work/nul.sl"

# One line of 1 MiB, in several shapes.
python3 -c 'import sys; sys.stdout.write("a" * (1 << 20))' >"$work/ident.sl"
check_rejected "a 1 MiB identifier" "$work/ident.sl"

python3 -c 'import sys; sys.stdout.write("surface s() { Ci = " + "(" * (1 << 20) + "; }")' \
	>"$work/parens.sl"
check_rejected "1 MiB of nested parentheses" "$work/parens.sl"

python3 -c 'import sys; sys.stdout.write("surface s() { Ci = " + "1+" * (1 << 19) + "; }")' \
	>"$work/sum.sl"
check_rejected "a 1 MiB expression missing its last operand" "$work/sum.sl"

python3 -c 'import sys; sys.stdout.write("surface s() { Ci = \"" + "x" * (1 << 20))' \
	>"$work/string.sl"
check_rejected "an unterminated 1 MiB string" "$work/string.sl"

python3 -c 'import sys; sys.stdout.write("surface s() " + "{" * (1 << 20))' >"$work/braces.sl"
check_rejected "1 MiB of open braces" "$work/braces.sl"

python3 -c 'import sys; sys.stdout.write("#define A(x) x x\n" + "A(" * 64 + "1" + ")" * 64 + "\n")' \
	>"$work/macro.sl"
check_rejected "macro calls that expand to 2^64 tokens" "$work/macro.sl"

printf '#include "self.sl"\n' >"$work/self.sl"
check_rejected "a file that includes itself" "$work/self.sl"

finish
