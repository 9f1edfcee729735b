import sys

from yarp_lite.cli import main

sys.exit(main())
