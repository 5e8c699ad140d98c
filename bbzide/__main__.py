"""`python -m bbzide` = the `bbzide` command."""

import sys

from bbzide.cli import main

sys.exit(main())
