#!/bin/sh
# Prints the first Python that has numpy, scipy and scikit-learn ($PYTHON,
# python3, /usr/bin/python3: a pyenv shim may hide Debian's packages);
# nothing, and exit status 1, when none has them.  Used by bench/run.sh
# and bench/solvers.sh.
for p in ${PYTHON:-} python3 /usr/bin/python3; do
    if command -v "$p" >/dev/null 2>&1 && "$p" -c 'import numpy, scipy, sklearn' 2>/dev/null; then
        echo "$p"
        exit 0
    fi
done
exit 1
