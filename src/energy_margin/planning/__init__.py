"""Tree growth over physics: the EST and its density estimate."""

from energy_margin.planning.est import CostField, TreeBudget, grow_tree, grow_trees_together

__all__ = ["CostField", "TreeBudget", "grow_tree", "grow_trees_together"]
