import sys

from lab.results.build import main

sys.exit(main())
