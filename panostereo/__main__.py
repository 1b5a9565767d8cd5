import sys

from panostereo.cli import main

sys.exit(main())
