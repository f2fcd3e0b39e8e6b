#!/usr/bin/env bash
# `relight` and `relight compile`: help, version, usage errors.
source "$(dirname "$0")/lib.sh"

run "relight --help" "$relight" --help
expect_status 0
expect_stdout '^usage: relight '
expect_stdout '^  compile +[A-Z]'
expect_empty_stderr

run "relight -h" "$relight" -h
expect_status 0
expect_stdout '^usage: relight '

run "relight --version" "$relight" --version
expect_status 0
expect_stdout '^relight [0-9]+\.[0-9]+\.[0-9]+$'

run "relight with no command" "$relight"
expect_status 2
expect_stderr '^usage: relight '

run "unknown command" "$relight" frobnicate
expect_status 2
expect_stderr "'frobnicate' is not a relight command"
expect_stderr "relight --help"

run "misspelt command" "$relight" compil x.sl
expect_status 2
expect_stderr "Did you mean 'compile'"

run "unknown global option" "$relight" --frob
expect_status 2
expect_stderr "unknown option '--frob'"

run "relight help compile" "$relight" help compile
expect_status 0
expect_stdout '^usage: relight compile '

run "relight compile --help" "$relight" compile --help
expect_status 0
expect_stdout '^usage: relight compile '
# Every option is described.
for opt in '--emit KIND' '-I DIR' '--include DIR' '-D NAME' '--define NAME' '-o FILE' \
	'--output FILE' '-h, --help' 'ast ' 'ir ' 'report ' 'RELIGHT_SHADER_PATH' 'Exit status'; do
	expect_stdout "$(printf '%s' "$opt" | sed 's/[.[*^$]/\\&/g')"
done

run "compile: unknown long option" "$relight" compile --frobnicate x.sl
expect_status 2
expect_stderr "unknown option '--frobnicate'"

run "compile: unknown short option" "$relight" compile -q x.sl
expect_status 2
expect_stderr "unknown option '-q'"

run "compile: missing option argument" "$relight" compile x.sl --emit
expect_status 2
expect_stderr "option '--emit' needs an argument"

run "compile: bad --emit kind" "$relight" compile --emit pdf x.sl
expect_status 2
expect_stderr "unknown --emit kind 'pdf'"

run "compile: no input" "$relight" compile
expect_status 2
expect_stderr 'no input file'

run "compile: two inputs" "$relight" compile a.sl b.sl
expect_status 2
expect_stderr "extra argument 'b.sl'"

run "compile: bad -D" "$relight" compile -D 9x a.sl
expect_status 2
expect_stderr "bad definition '9x'"

run "compile: -o without --emit" "$relight" compile -o out.txt a.sl
expect_status 2
expect_stderr '-o needs --emit'

finish
