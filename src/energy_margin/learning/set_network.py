"""A permutation-invariant network over the objects of a frame: the ``set`` learned margin.

The network reads every object's channels and the frame's summary features
(:class:`~energy_margin.learning.features.ObjectSetFeatures`) and predicts both scores:

1. **Encoder** φ: each object's standardised channels through two ReLU layers, shape (N, H).
2. **Interaction**: one block of scaled dot-product self-attention over the objects (a single
   head; padded rows are never attended to) added to the encodings, then a ReLU feed-forward layer
   added again. Objects push each other: whether one stays in the region depends on its
   neighbours, which a sum of independent encodings cannot see.
3. **Pooling**: the masked mean and the masked maximum over the objects, (2H,), so the output does
   not depend on the order of the objects and any number of them fits.
4. **Head** ρ: the pooled encoding beside one ReLU layer of the standardised frame features,
   through a ReLU layer to two logits; the outputs are their sigmoids, the capture and success
   scores in [0, 1].

PyTorch fits it (:func:`fit_set_regressor`, the ``learn`` extra; on the CPU, in float32, with Adam,
a binary cross-entropy against the tree's scores and early stopping on held-out trajectories).
What is kept and saved is only the weights as arrays: :class:`SetRegressor` predicts with numpy
alone, so scoring with a fitted model needs no PyTorch, and the tests check that both give the same
outputs.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import numpy as np

from energy_margin.errors import InvalidDataError, InvalidParameterError
from energy_margin.learning.features import SetInputs

__all__ = [
    "DEFAULTS",
    "KIND",
    "LOSSES",
    "N_OUTPUTS",
    "SetRegressor",
    "fit_set_regressor",
]

#: Kind name of the set regressor in a model file.
KIND = "set"
#: Targets predicted together: the capture and the success score.
N_OUTPUTS = 2
#: Names of the weight arrays, in the order of the layers.
_WEIGHTS = (
    "encoder_0",
    "encoder_1",
    "query",
    "key",
    "value",
    "attention_out",
    "feed_forward",
    "frame_0",
    "head_0",
    "head_1",
)
#: The layers with a bias (the attention projections have none).
_BIASED = ("encoder_0", "encoder_1", "attention_out", "feed_forward", "frame_0", "head_0", "head_1")
#: Default settings of :func:`fit_set_regressor`.
DEFAULTS: dict[str, Any] = {
    "hidden": 64,
    "epochs": 400,
    "patience": 40,
    "batch_size": 128,
    "learning_rate": 2e-3,
    "weight_decay": 1e-4,
    "validation": 0.15,
    "threads": 1,
    "loss": "bce",
    "success_weight": 1.0,
    "auxiliary": None,
    "auxiliary_weight": 0.5,
}
#: Losses of :func:`fit_set_regressor`: binary cross-entropy against the scores, or the squared error
#: of the logits against the scores' logits (scores clipped to [1e-3, 1 - 1e-3]), which weighs the
#: small scores of early frames as much as the large ones.
LOSSES = ("bce", "logit")
_LOGIT_FLOOR = 1e-3


def _sigmoid(values: np.ndarray) -> np.ndarray:
    return 0.5 * (1.0 + np.tanh(0.5 * values))


class SetRegressor:
    """The fitted set network as arrays, with a numpy forward pass.

    Args:
        object_mean: per-object channel means, shape (C,).
        object_scale: per-object channel standard deviations, shape (C,), > 0.
        frame_mean: frame feature means, shape (D,).
        frame_scale: frame feature standard deviations, shape (D,), > 0.
        weights: ``name -> matrix`` for every name of the layers (module docstring): shapes
            (C, H), (H, H), three (H, H), (H, H), (H, H), (D, H), (3H, H), (H, 2).
        biases: ``name -> vector`` of the biased layers, shapes (H,) or (2,).
    """

    kind = KIND

    def __init__(
        self,
        object_mean: np.ndarray,
        object_scale: np.ndarray,
        frame_mean: np.ndarray,
        frame_scale: np.ndarray,
        weights: dict[str, np.ndarray],
        biases: dict[str, np.ndarray],
    ) -> None:
        for name, mean, scale in (("object", object_mean, object_scale), ("frame", frame_mean, frame_scale)):
            if mean.ndim != 1 or scale.shape != mean.shape or not np.all(scale > 0):
                raise InvalidDataError(f"{name}_mean and {name}_scale must be vectors of one length, scale > 0")
        missing = [name for name in _WEIGHTS if name not in weights] + [name for name in _BIASED if name not in biases]
        if missing:
            raise InvalidDataError(f"missing layers: {', '.join(missing)}")
        hidden = weights["encoder_0"].shape[1] if weights["encoder_0"].ndim == 2 else -1
        channels, width = object_mean.shape[0], frame_mean.shape[0]
        expected = {
            "encoder_0": (channels, hidden),
            "encoder_1": (hidden, hidden),
            "query": (hidden, hidden),
            "key": (hidden, hidden),
            "value": (hidden, hidden),
            "attention_out": (hidden, hidden),
            "feed_forward": (hidden, hidden),
            "frame_0": (width, hidden),
            "head_0": (3 * hidden, hidden),
            "head_1": (hidden, weights["head_1"].shape[1] if weights["head_1"].ndim == 2 else -1),
        }
        if expected["head_1"][1] < N_OUTPUTS:
            raise InvalidDataError(f"layer head_1 has {expected['head_1'][1]} outputs, expected >= {N_OUTPUTS}")
        for name, shape in expected.items():
            if weights[name].shape != shape:
                raise InvalidDataError(f"layer {name} has weights {weights[name].shape}, expected {shape}")
            if name in _BIASED and biases[name].shape != (shape[1],):
                raise InvalidDataError(f"layer {name} has bias {biases[name].shape}, expected {(shape[1],)}")
        self.object_mean, self.object_scale = object_mean, object_scale
        self.frame_mean, self.frame_scale = frame_mean, frame_scale
        self.weights, self.biases = weights, biases
        self._weights32 = {name: value.astype(np.float32) for name, value in weights.items()}
        self._biases32 = {name: value.astype(np.float32) for name, value in biases.items()}
        #: What the fit measured (:func:`fit_set_regressor`); empty for a loaded model.
        self.fit_info: dict[str, Any] = {}

    @property
    def n_features(self) -> int:
        """Number of per-object channels plus frame features, C + D."""
        return int(self.object_mean.shape[0] + self.frame_mean.shape[0])

    @property
    def hidden(self) -> int:
        """Width H of every hidden layer."""
        return int(self.weights["encoder_0"].shape[1])

    def predict(self, inputs: SetInputs) -> np.ndarray:
        """Capture and success scores, shape (F, 2), in [0, 1], of ``inputs`` (F frames).

        Computed in float32 (the precision it was fitted in), which halves the time of the
        matrix products against float64.
        """
        w, b = self._weights32, self._biases32
        mask = inputs.mask
        objects = ((inputs.objects - self.object_mean) / self.object_scale).astype(np.float32)  # (F, N, C)
        hidden = np.maximum(objects @ w["encoder_0"] + b["encoder_0"], 0.0)
        hidden = np.maximum(hidden @ w["encoder_1"] + b["encoder_1"], 0.0)  # (F, N, H)
        query, key, value = hidden @ w["query"], hidden @ w["key"], hidden @ w["value"]
        logits = np.matmul(query, key.transpose(0, 2, 1)) * np.float32(1.0 / np.sqrt(self.hidden))  # (F, N, N)
        logits = np.where(mask[:, None, :], logits, np.float32(-np.inf))
        logits -= logits.max(axis=2, keepdims=True)
        attention = np.exp(logits)
        attention /= attention.sum(axis=2, keepdims=True)
        hidden = hidden + np.matmul(attention, value) @ w["attention_out"] + b["attention_out"]
        hidden = hidden + np.maximum(hidden @ w["feed_forward"] + b["feed_forward"], 0.0)
        weight = mask[:, :, None].astype(np.float32)
        count = np.maximum(weight.sum(axis=1), 1.0)
        mean = (hidden * weight).sum(axis=1) / count
        maximum = np.where(mask[:, :, None], hidden, np.float32(-np.inf)).max(axis=1)
        frame = ((inputs.frame - self.frame_mean) / self.frame_scale).astype(np.float32)
        frame_hidden = np.maximum(frame @ w["frame_0"] + b["frame_0"], 0.0)
        head = np.concatenate([mean, maximum, frame_hidden], axis=1)
        head = np.maximum(head @ w["head_0"] + b["head_0"], 0.0)
        # Outputs past the first two are the auxiliary heads of the fit (labels), not scores.
        logits_out = head @ w["head_1"][:, :N_OUTPUTS] + b["head_1"][:N_OUTPUTS]
        return np.asarray(_sigmoid(logits_out.astype(float)))

    def arrays(self) -> dict[str, np.ndarray]:
        """The parameters by name (what :meth:`from_arrays` reads back)."""
        arrays = {
            "object_mean": self.object_mean,
            "object_scale": self.object_scale,
            "frame_mean": self.frame_mean,
            "frame_scale": self.frame_scale,
        }
        arrays.update({f"weight.{name}": value for name, value in self.weights.items()})
        arrays.update({f"bias.{name}": value for name, value in self.biases.items()})
        return arrays

    @classmethod
    def from_arrays(cls, arrays: dict[str, np.ndarray]) -> SetRegressor:
        """Rebuild from :meth:`arrays`.

        Raises:
            InvalidDataError: a missing array or arrays that do not fit together.
        """
        try:
            return cls(
                np.asarray(arrays["object_mean"], dtype=float),
                np.asarray(arrays["object_scale"], dtype=float),
                np.asarray(arrays["frame_mean"], dtype=float),
                np.asarray(arrays["frame_scale"], dtype=float),
                {name: np.asarray(arrays[f"weight.{name}"], dtype=float) for name in _WEIGHTS},
                {name: np.asarray(arrays[f"bias.{name}"], dtype=float) for name in _BIASED},
            )
        except KeyError as error:
            raise InvalidDataError(f"array {error.args[0]!r} is missing") from None


def _standardiser(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mean and standard deviation of the rows of ``values`` (R, K); a constant column gets scale 1."""
    mean = values.mean(axis=0)
    scale = values.std(axis=0)
    return mean, np.where(scale > 1e-9, scale, 1.0)


def fit_set_regressor(
    inputs: SetInputs,
    targets: np.ndarray,
    *,
    seed: int,
    groups: np.ndarray | None = None,
    **options: Any,
) -> tuple[SetRegressor, dict[str, Any]]:
    """Fit the set network to ``targets`` with PyTorch on the CPU.

    Args:
        inputs: training inputs of F frames.
        targets: the tree's capture and success scores, shape (F, 2), in [0, 1].
        seed: seeds the weights, the validation split and the batch order.
        groups: trajectory of each frame, shape (F,); the validation split for early stopping
            holds out whole groups (default: every frame its own group).
        options: ``hidden`` (width H, default 64), ``epochs`` (most passes, 400), ``patience``
            (passes without a better validation loss before stopping, 40), ``batch_size`` (128),
            ``learning_rate`` (Adam, 2e-3), ``weight_decay`` (1e-4), ``validation`` (fraction of
            groups held out for early stopping, 0.15), ``threads`` (PyTorch threads, 1).

    Returns:
        The regressor with the weights of the best validation loss, and what the fit measured:
        ``epochs`` run, ``best_epoch``, ``validation_loss``, ``fit_seconds``.

    Raises:
        EnergyMarginError: PyTorch is not installed (naming the extra).
        InvalidParameterError: an unknown option, or targets of the wrong shape.
    """
    settings, targets = _settings_and_targets(inputs, targets, options)
    torch = _import_torch()
    started = time.perf_counter()
    rng = np.random.default_rng(seed)
    groups = np.arange(len(inputs)) if groups is None else np.asarray(groups)
    unique = rng.permutation(np.unique(groups))
    n_validation = min(len(unique) - 1, max(1, round(settings["validation"] * len(unique))))
    validation_rows = np.isin(groups, unique[:n_validation])
    object_mean, object_scale = _standardiser(inputs.objects[inputs.mask])
    frame_mean, frame_scale = _standardiser(inputs.frame)

    def tensors(rows: np.ndarray) -> tuple[Any, ...]:
        part = inputs.take(rows)
        return (
            torch.as_tensor((part.objects - object_mean) / object_scale, dtype=torch.float32),
            torch.as_tensor(part.mask),
            torch.as_tensor((part.frame - frame_mean) / frame_scale, dtype=torch.float32),
            torch.as_tensor(targets[rows], dtype=torch.float32),
        )

    train = tensors(np.flatnonzero(~validation_rows))
    validation = tensors(np.flatnonzero(validation_rows))
    previous_threads = torch.get_num_threads()
    torch.set_num_threads(int(settings["threads"]))
    try:
        torch.manual_seed(int(np.random.SeedSequence(seed).generate_state(1)[0]))
        network = _torch_network(
            torch, inputs.objects.shape[2], inputs.frame.shape[1], int(settings["hidden"]), targets.shape[1]
        )
        best_loss, best_epoch, epoch = _train(torch, network, settings, targets.shape[1], train, validation, rng)
    finally:
        torch.set_num_threads(previous_threads)
    regressor = _from_torch(network, object_mean, object_scale, frame_mean, frame_scale)
    return regressor, {
        "epochs": epoch + 1,
        "best_epoch": best_epoch + 1,
        "validation_loss": best_loss,
        "fit_seconds": time.perf_counter() - started,
        "settings": settings,
    }


def _settings_and_targets(
    inputs: SetInputs, targets: np.ndarray, options: dict[str, Any]
) -> tuple[dict[str, Any], np.ndarray]:
    """The options over :data:`DEFAULTS` (less ``auxiliary``); the scores and A auxiliaries, (F, 2 + A).

    Raises:
        InvalidParameterError: an unknown option, or targets of the wrong shape.
    """
    unknown = sorted(set(options) - set(DEFAULTS))
    if unknown:
        raise InvalidParameterError(
            "options", f"names unknown set options: {', '.join(unknown)} (known: {', '.join(DEFAULTS)})"
        )
    settings = {**DEFAULTS, **options}
    targets = np.asarray(targets, dtype=float)
    if targets.shape != (len(inputs), N_OUTPUTS):
        raise InvalidParameterError("targets", f"must have shape {(len(inputs), N_OUTPUTS)}, got {targets.shape}")
    auxiliary = settings.pop("auxiliary")
    if auxiliary is not None:
        auxiliary = np.asarray(auxiliary, dtype=float).reshape(len(inputs), -1)
        targets = np.concatenate([targets, auxiliary], axis=1)
    return settings, targets


def _import_torch() -> Any:
    """The ``torch`` module, or an error naming the extra that installs it."""
    from energy_margin.errors import EnergyMarginError

    try:
        import torch
    except ImportError:
        raise EnergyMarginError(
            "the set margin model is fitted with PyTorch: pip install 'energy-margin[learn]'"
        ) from None
    return torch


def _loss_function(torch: Any, settings: dict[str, Any], n_targets: int) -> Callable[[Any, Any], Any]:
    """The weighted loss of logits against scores, both shape (B, n_targets): BCE or logit MSE."""
    from energy_margin.errors import check_choice

    check_choice("loss", settings["loss"], LOSSES)
    weights = torch.as_tensor(
        [1.0, float(settings["success_weight"])] + [float(settings["auxiliary_weight"])] * (n_targets - N_OUTPUTS),
        dtype=torch.float32,
    )
    if settings["loss"] == "bce":
        bce = torch.nn.BCEWithLogitsLoss(reduction="none")

        def loss_function(logits: Any, scores: Any) -> Any:
            return (bce(logits, scores) * weights).mean()

    else:

        def loss_function(logits: Any, scores: Any) -> Any:
            clipped = scores.clamp(_LOGIT_FLOOR, 1.0 - _LOGIT_FLOOR)
            return (((logits - torch.log(clipped / (1.0 - clipped))) ** 2) * weights).mean()

    return loss_function


def _train(
    torch: Any,
    network: Any,
    settings: dict[str, Any],
    n_targets: int,
    train: tuple[Any, ...],
    validation: tuple[Any, ...],
    rng: np.random.Generator,
) -> tuple[float, int, int]:
    """Adam on shuffled batches with early stopping; leaves ``network`` with its best weights.

    Returns:
        The best validation loss, its epoch and the last epoch run (0-based).
    """
    optimiser = torch.optim.Adam(
        network.parameters(), lr=settings["learning_rate"], weight_decay=settings["weight_decay"]
    )
    loss_function = _loss_function(torch, settings, n_targets)
    best_loss, best_epoch, best_state, epoch = float("inf"), -1, None, 0
    count = train[0].shape[0]
    for epoch in range(int(settings["epochs"])):
        network.train()
        order = rng.permutation(count)
        for start in range(0, count, int(settings["batch_size"])):
            rows = torch.as_tensor(order[start : start + int(settings["batch_size"])])
            optimiser.zero_grad()
            loss = loss_function(network(train[0][rows], train[1][rows], train[2][rows]), train[3][rows])
            loss.backward()
            optimiser.step()
        network.eval()
        with torch.no_grad():
            validation_loss = float(loss_function(network(*validation[:3]), validation[3]))
        if validation_loss < best_loss - 1e-6:
            best_loss, best_epoch = validation_loss, epoch
            best_state = {name: value.detach().clone() for name, value in network.state_dict().items()}
        elif epoch - best_epoch >= int(settings["patience"]):
            break
    assert best_state is not None
    network.load_state_dict(best_state)
    return best_loss, best_epoch, epoch


def _from_torch(
    network: Any, object_mean: np.ndarray, object_scale: np.ndarray, frame_mean: np.ndarray, frame_scale: np.ndarray
) -> SetRegressor:
    """The :class:`SetRegressor` of a PyTorch network of :func:`_torch_network` and its standardisers."""
    state = {name: value.detach().double().numpy() for name, value in network.state_dict().items()}
    return SetRegressor(
        object_mean,
        object_scale,
        frame_mean,
        frame_scale,
        {name: state[f"{name}.weight"].T.copy() for name in _WEIGHTS},
        {name: state[f"{name}.bias"].copy() for name in _BIASED},
    )


def _torch_network(torch: Any, channels: int, width: int, hidden: int, outputs: int = N_OUTPUTS) -> Any:
    """The PyTorch module of the network (logits out); its layer names are those of :data:`_WEIGHTS`."""
    nn = torch.nn

    class Network(nn.Module):  # type: ignore[name-defined]
        def __init__(self) -> None:
            super().__init__()
            self.encoder_0 = nn.Linear(channels, hidden)
            self.encoder_1 = nn.Linear(hidden, hidden)
            self.query = nn.Linear(hidden, hidden, bias=False)
            self.key = nn.Linear(hidden, hidden, bias=False)
            self.value = nn.Linear(hidden, hidden, bias=False)
            self.attention_out = nn.Linear(hidden, hidden)
            self.feed_forward = nn.Linear(hidden, hidden)
            self.frame_0 = nn.Linear(width, hidden)
            self.head_0 = nn.Linear(3 * hidden, hidden)
            self.head_1 = nn.Linear(hidden, outputs)

        def forward(self, objects: Any, mask: Any, frame: Any) -> Any:
            relu = torch.relu
            hidden_ = relu(self.encoder_1(relu(self.encoder_0(objects))))
            logits = torch.einsum("fnh,fmh->fnm", self.query(hidden_), self.key(hidden_)) / hidden**0.5
            logits = logits.masked_fill(~mask[:, None, :], float("-inf"))
            attention = torch.softmax(logits, dim=2)
            hidden_ = hidden_ + self.attention_out(torch.einsum("fnm,fmh->fnh", attention, self.value(hidden_)))
            hidden_ = hidden_ + relu(self.feed_forward(hidden_))
            weight = mask[:, :, None].to(hidden_.dtype)
            mean = (hidden_ * weight).sum(dim=1) / weight.sum(dim=1).clamp(min=1.0)
            maximum = hidden_.masked_fill(~mask[:, :, None], float("-inf")).amax(dim=1)
            head = torch.cat([mean, maximum, relu(self.frame_0(frame))], dim=1)
            return self.head_1(relu(self.head_0(head)))

    return Network()
