import sys

from servoface.controller.cli import main

sys.exit(main())
