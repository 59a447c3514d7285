#!/bin/sh
# run_pytest.sh - one pytest module of the Python package under ctest:
#   run_pytest.sh PYTHON TEST_FILE...
# Exits 77 (skipped) where the interpreter lacks numpy or pytest (Debian's
# python3-numpy, python3-pytest); conftest.py exits 77 where skyd finds no
# Vulkan device.
py=$1
shift
if ! "$py" -c 'import numpy, pytest' 2>/dev/null; then
	echo "skipped: $py lacks numpy or pytest (apt-get install python3-numpy python3-pytest)"
	exit 77
fi
exec "$py" -m pytest -q -rs -p no:cacheprovider "$@"
