"""Reproduce the paper's Table/figures numbers: python experiments/paper/reproduce.py --alpha 4 --alpha 10 --seeds 10 --out DIR"""

from torchpaml.cli import main

if __name__ == "__main__":
    main(["paper"], prog="experiments/paper/reproduce.py")
