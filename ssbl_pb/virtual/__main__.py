"""``python -m ssbl_pb.virtual``: the virtual Pepper (``virtual.pepper``)."""

from ..cli import run
from .pepper import main

if __name__ == "__main__":
    run(main)
