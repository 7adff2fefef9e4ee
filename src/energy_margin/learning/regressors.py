"""The fitted regressors of a learned margin as plain arrays, with their own vectorised prediction.

scikit-learn fits them; what a margin model keeps and saves is only their parameters (weights,
split thresholds, leaf values) as numpy arrays, so a saved model loads without running code from
the file (no pickle) and predicts with a few matrix products or array look-ups.

* :class:`MlpRegressor`: a standardising scaler and a ReLU multi-layer perceptron with one linear
  output per score (scikit-learn's ``MLPRegressor``).
* :class:`BoostingRegressor`: per score, gradient-boosted regression trees
  (``HistGradientBoostingRegressor``), all trees of a score traversed together, depth by depth.

Both predict raw values; the margin model clips them to [0, 1].
"""

from __future__ import annotations

from typing import Any, Protocol

import numpy as np

from energy_margin.errors import InvalidDataError, InvalidParameterError, check_choice

__all__ = [
    "DEFAULT_KIND",
    "KINDS",
    "N_OUTPUTS",
    "BoostingRegressor",
    "MlpRegressor",
    "Regressor",
    "fit_regressor",
    "regressor_from_arrays",
]

#: Targets predicted together: the capture and the success score.
N_OUTPUTS = 2
#: Regressor kinds: a perceptron and boosted trees over frame statistics, the set network over objects.
KINDS = ("mlp", "boosting", "set")
#: The kind fitted when none is asked for, in Python and on the command line: the set network.
DEFAULT_KIND = "set"


class Regressor(Protocol):
    """Raw predictions of the two scores from features."""

    kind: str

    @property
    def n_features(self) -> int:
        """Number of features D it was fitted on."""
        ...

    def predict(self, features: Any) -> np.ndarray:
        """Raw predictions, shape (F, 2), from ``features`` (F, D) (set inputs for the ``set`` kind)."""
        ...

    def arrays(self) -> dict[str, np.ndarray]:
        """The parameters by name (what :func:`regressor_from_arrays` reads back)."""
        ...


class MlpRegressor:
    """A standardised-input ReLU perceptron with linear outputs.

    Args:
        mean: feature means, shape (D,).
        scale: feature standard deviations, shape (D,), > 0.
        weights: layer weight matrices, shapes (D, H1), (H1, H2), ..., (Hk, 2).
        biases: layer biases, shapes (H1,), ..., (2,).
    """

    kind = "mlp"

    def __init__(
        self, mean: np.ndarray, scale: np.ndarray, weights: list[np.ndarray], biases: list[np.ndarray]
    ) -> None:
        if not weights or len(weights) != len(biases):
            raise InvalidDataError("weights and biases must be non-empty lists of the same length")
        if mean.ndim != 1 or scale.shape != mean.shape or not np.all(scale > 0):
            raise InvalidDataError("mean and scale must be vectors of the same length, scale > 0")
        width = mean.shape[0]
        for index, (weight, bias) in enumerate(zip(weights, biases, strict=True)):
            if weight.ndim != 2 or weight.shape[0] != width or bias.shape != (weight.shape[1],):
                raise InvalidDataError(
                    f"layer {index} has weights {weight.shape} and bias {bias.shape} after width {width}"
                )
            width = weight.shape[1]
        if width != N_OUTPUTS:
            raise InvalidDataError(f"the last layer must have {N_OUTPUTS} outputs, got {width}")
        self.mean, self.scale, self.weights, self.biases = mean, scale, weights, biases

    @property
    def n_features(self) -> int:
        """Number of features D."""
        return int(self.mean.shape[0])

    @classmethod
    def from_sklearn(cls, scaler: Any, mlp: Any) -> MlpRegressor:
        """From a fitted ``StandardScaler`` and ``MLPRegressor`` (activation ``relu``, two outputs)."""
        if mlp.activation != "relu":
            raise InvalidParameterError(
                "mlp", f"must use the relu activation, the only one exported, got {mlp.activation!r}"
            )
        return cls(
            np.asarray(scaler.mean_, dtype=float),
            np.asarray(scaler.scale_, dtype=float),
            [np.asarray(w, dtype=float) for w in mlp.coefs_],
            [np.asarray(b, dtype=float) for b in mlp.intercepts_],
        )

    def predict(self, features: np.ndarray) -> np.ndarray:
        """Raw predictions, shape (F, 2)."""
        hidden = (features - self.mean) / self.scale
        last = len(self.weights) - 1
        for index, (weight, bias) in enumerate(zip(self.weights, self.biases, strict=True)):
            hidden = hidden @ weight + bias
            if index < last:
                np.maximum(hidden, 0.0, out=hidden)
        return hidden

    def arrays(self) -> dict[str, np.ndarray]:
        """``mean``, ``scale``, ``weight_i``, ``bias_i``."""
        arrays = {"mean": self.mean, "scale": self.scale}
        for index, (weight, bias) in enumerate(zip(self.weights, self.biases, strict=True)):
            arrays[f"weight_{index}"] = weight
            arrays[f"bias_{index}"] = bias
        return arrays


class BoostingRegressor:
    """Sums of regression trees, one ensemble per score, stored as padded node arrays.

    Args:
        baseline: initial prediction of each score, shape (2,).
        feature: split feature of every node, shape (2, n_trees, max_nodes), int (any value at leaves).
        threshold: split threshold, same shape; a sample goes left when its feature is <= it.
        left: left child index, same shape (a leaf points to itself).
        right: right child index, same shape (a leaf points to itself).
        value: leaf value (learning rate included), same shape (0 at split nodes).
        depth: largest depth of any tree (traversal steps).
        n_features: number of features D it was fitted on (every split feature is below it).
    """

    kind = "boosting"

    def __init__(
        self,
        baseline: np.ndarray,
        feature: np.ndarray,
        threshold: np.ndarray,
        left: np.ndarray,
        right: np.ndarray,
        value: np.ndarray,
        depth: int,
        n_features: int,
    ) -> None:
        shape = feature.shape
        if baseline.shape != (N_OUTPUTS,) or len(shape) != 3 or shape[0] != N_OUTPUTS:
            raise InvalidDataError(f"baseline must have shape ({N_OUTPUTS},) and nodes ({N_OUTPUTS}, trees, nodes)")
        for name, array in (("threshold", threshold), ("left", left), ("right", right), ("value", value)):
            if array.shape != shape:
                raise InvalidDataError(f"{name} has shape {array.shape}, expected {shape}")
        for name, array in (("feature", feature), ("left", left), ("right", right)):
            if array.dtype.kind not in "iu":
                raise InvalidDataError(f"{name} must hold integers, got {array.dtype}")
        if shape[2] and (left.min() < 0 or right.min() < 0 or left.max() >= shape[2] or right.max() >= shape[2]):
            raise InvalidDataError("child indices point outside the node arrays")
        if feature.min(initial=0) < 0 or feature.max(initial=0) >= n_features:
            raise InvalidDataError(f"split features must lie in [0, {n_features})")
        if depth < 0 or depth > max(shape[2] - 1, 0):
            raise InvalidDataError(
                f"depth must be in [0, {max(shape[2] - 1, 0)}] for trees of {shape[2]} nodes, got {depth}"
            )
        self.baseline = baseline
        self.feature = feature.astype(np.int64)
        self.threshold, self.value = threshold, value
        self.left, self.right = left.astype(np.int64), right.astype(np.int64)
        self.depth = int(depth)
        self._n_features = int(n_features)

    @property
    def n_features(self) -> int:
        """Number of features D."""
        return self._n_features

    @classmethod
    def from_sklearn(cls, models: list[Any]) -> BoostingRegressor:
        """From one fitted ``HistGradientBoostingRegressor`` per score (numerical features, squared error)."""
        if len(models) != N_OUTPUTS:
            raise InvalidParameterError("models", f"must hold {N_OUTPUTS} fitted models, got {len(models)}")
        trees = [[iteration[0].nodes for iteration in model._predictors] for model in models]
        n_trees = max(len(ensemble) for ensemble in trees)
        max_nodes = max((len(nodes) for ensemble in trees for nodes in ensemble), default=1)
        shape = (N_OUTPUTS, n_trees, max_nodes)
        feature = np.zeros(shape, dtype=np.int64)
        threshold = np.zeros(shape)
        own = np.broadcast_to(np.arange(max_nodes), shape)
        left, right = own.copy(), own.copy()
        value = np.zeros(shape)
        depth = 0
        for output, ensemble in enumerate(trees):
            for tree, nodes in enumerate(ensemble):
                count = len(nodes)
                leaf = nodes["is_leaf"].astype(bool)
                feature[output, tree, :count] = np.where(leaf, 0, nodes["feature_idx"])
                threshold[output, tree, :count] = nodes["num_threshold"]
                left[output, tree, :count] = np.where(leaf, np.arange(count), nodes["left"])
                right[output, tree, :count] = np.where(leaf, np.arange(count), nodes["right"])
                value[output, tree, :count] = np.where(leaf, nodes["value"], 0.0)
                depth = max(depth, int(nodes["depth"].max()))
        baseline = np.array([float(np.ravel(model._baseline_prediction)[0]) for model in models])
        return cls(baseline, feature, threshold, left, right, value, depth, int(models[0].n_features_in_))

    def predict(self, features: np.ndarray) -> np.ndarray:
        """Raw predictions, shape (F, 2)."""
        out = np.empty((features.shape[0], N_OUTPUTS))
        n_trees = self.feature.shape[1]
        trees = np.arange(n_trees)[:, None]
        samples = np.arange(features.shape[0])[None, :]
        for output in range(N_OUTPUTS):
            feature, threshold = self.feature[output], self.threshold[output]
            left, right = self.left[output], self.right[output]
            node = np.zeros((n_trees, features.shape[0]), dtype=np.int64)
            for _ in range(self.depth):
                goes_left = features[samples, feature[trees, node]] <= threshold[trees, node]
                node = np.where(goes_left, left[trees, node], right[trees, node])
            out[:, output] = self.baseline[output] + self.value[output][trees, node].sum(axis=0)
        return out

    def arrays(self) -> dict[str, np.ndarray]:
        """``baseline``, ``feature``, ``threshold``, ``left``, ``right``, ``value``, ``depth``, ``n_features``."""
        return {
            "baseline": self.baseline,
            "feature": self.feature,
            "threshold": self.threshold,
            "left": self.left,
            "right": self.right,
            "value": self.value,
            "depth": np.array(self.depth),
            "n_features": np.array(self._n_features),
        }


def regressor_from_arrays(kind: str, arrays: dict[str, np.ndarray]) -> Regressor:
    """Rebuild a regressor of ``kind`` from :meth:`Regressor.arrays`.

    Raises:
        InvalidDataError: an unknown kind, a missing array or arrays that do not fit together.
    """
    try:
        if kind == "mlp":
            layers = sum(1 for name in arrays if name.startswith("weight_"))
            return MlpRegressor(
                np.asarray(arrays["mean"], dtype=float),
                np.asarray(arrays["scale"], dtype=float),
                [np.asarray(arrays[f"weight_{i}"], dtype=float) for i in range(layers)],
                [np.asarray(arrays[f"bias_{i}"], dtype=float) for i in range(layers)],
            )
        if kind == "set":
            from energy_margin.learning.set_network import SetRegressor

            return SetRegressor.from_arrays(arrays)
        if kind == "boosting":
            return BoostingRegressor(
                np.asarray(arrays["baseline"], dtype=float),
                np.asarray(arrays["feature"]),
                np.asarray(arrays["threshold"], dtype=float),
                np.asarray(arrays["left"]),
                np.asarray(arrays["right"]),
                np.asarray(arrays["value"], dtype=float),
                int(arrays["depth"]),
                int(arrays["n_features"]),
            )
    except KeyError as error:
        raise InvalidDataError(f"array {error.args[0]!r} is missing") from None
    raise InvalidDataError(f"unknown regressor kind {kind!r} (known: {', '.join(KINDS)})")


def fit_regressor(kind: str, features: Any, targets: np.ndarray, *, seed: int, **options: Any) -> Regressor:
    """Fit a regressor of ``kind`` to ``targets`` (F, 2) from ``features`` (F, D) with scikit-learn.

    The ``set`` kind is fitted with PyTorch instead
    (:func:`energy_margin.learning.set_network.fit_set_regressor`, whose options it takes, ``groups``
    included); its ``features`` are :class:`~energy_margin.learning.features.SetInputs` and what the fit
    measured is kept as the regressor's ``fit_info``.

    Args:
        kind: ``"mlp"``, ``"boosting"`` or ``"set"``.
        features: training features, shape (F, D) (``SetInputs`` of F frames for ``set``).
        targets: capture and success scores, shape (F, 2).
        seed: the regressor's random state.
        options: ``hidden`` (MLP layer widths, default (64, 64)), ``alpha`` (MLP L2 penalty,
            default 1e-3), ``max_iter`` (MLP epochs, default 2000; boosting rounds, default 150),
            ``learning_rate`` (boosting, default 0.1), ``max_depth`` (boosting, default 4).

    scikit-learn's native thread pools are held to one thread while fitting: on a busy machine
    (the analysis workers of the same run) an oversubscribed OpenMP pool made a boosting fit
    tens of times slower, and the training sets here are a few thousand frames.

    Raises:
        InvalidParameterError: an unknown kind or option.
    """
    from threadpoolctl import threadpool_limits

    check_choice("kind", kind, KINDS)
    if kind == "set":
        from energy_margin.learning.set_network import fit_set_regressor

        regressor, info = fit_set_regressor(features, targets, seed=seed, **options)
        regressor.fit_info = info
        return regressor
    options.pop("groups", None)
    with threadpool_limits(limits=1):
        return _fit(kind, features, targets, seed=seed, **options)


def _fit(kind: str, features: np.ndarray, targets: np.ndarray, *, seed: int, **options: Any) -> Regressor:
    if kind == "mlp":
        from sklearn.neural_network import MLPRegressor
        from sklearn.preprocessing import StandardScaler

        unknown = sorted(set(options) - {"hidden", "alpha", "max_iter"})
        if unknown:
            raise InvalidParameterError("options", f"names unknown mlp options: {', '.join(unknown)}")
        scaler = StandardScaler().fit(features)
        # A constant feature (e.g. the number of objects of a single dataset) has scale 1.
        mlp = MLPRegressor(
            hidden_layer_sizes=tuple(options.get("hidden", (64, 64))),
            activation="relu",
            alpha=float(options.get("alpha", 1e-3)),
            max_iter=int(options.get("max_iter", 2000)),
            early_stopping=True,
            n_iter_no_change=30,
            random_state=seed,
        )
        mlp.fit(scaler.transform(features), targets)
        return MlpRegressor.from_sklearn(scaler, mlp)
    if kind == "boosting":
        from sklearn.ensemble import HistGradientBoostingRegressor

        unknown = sorted(set(options) - {"max_iter", "learning_rate", "max_depth"})
        if unknown:
            raise InvalidParameterError("options", f"names unknown boosting options: {', '.join(unknown)}")
        models = [
            HistGradientBoostingRegressor(
                max_iter=int(options.get("max_iter", 150)),
                learning_rate=float(options.get("learning_rate", 0.1)),
                max_depth=int(options.get("max_depth", 4)),
                early_stopping=False,
                random_state=seed,
            ).fit(features, targets[:, output])
            for output in range(N_OUTPUTS)
        ]
        return BoostingRegressor.from_sklearn(models)
    raise AssertionError(kind)  # fit_regressor checked the kind
