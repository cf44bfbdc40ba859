import os
import sys

try:
    from app.cli import main
except (KeyboardInterrupt, ImportError) as exc:
    # Ctrl-C while the command line loads (inside a C extension's import it comes out as an ImportError): answered
    # as one during the command, app.cli's failure line and object written out here since it did not load.
    cause = exc
    while cause is not None and not isinstance(cause, KeyboardInterrupt):
        cause = cause.__cause__ or cause.__context__
    if cause is None:
        raise
    print("error: interrupted", file=sys.stderr, flush=True)
    if "--json" in sys.argv[1:]:
        answer = '{"success":false,"error":{"code":"PREEMPTED","message":"interrupted"},"exit_code":130}\n'
        sys.stdout.write(answer)
        sys.stdout.flush()
    sys.exit(130)

code = main()
if "ompl" in sys.modules:
    # OMPL's nanobind bindings report "leaked" objects at interpreter shutdown (harmless); a user should not read
    # that after a clean run, so the process ends here.
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)
sys.exit(code)
