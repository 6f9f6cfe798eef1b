"""Support vector machines: a binary and multi-class :class:`SVC` and the hierarchical multi-class
:class:`HierarchicalSVC` of method 1, trained by a compiled libsvm solver.

One file per part:

- :mod:`~tactile_torch.svm.kernels`: the kernel matrix (torch), ``gamma="scale"``, and the kernel
  values the compiled code reads (computed rows, or one precomputed float32 matrix);
- :mod:`~tactile_torch.svm._smo`: the compiled (numba) kernels: libsvm's SMO solver (second-order
  working-set selection, shrinking, an LRU cache of kernel rows) and the decision values;
- :mod:`~tactile_torch.svm.solver`: the binary C-SVC dual, problem sets, warm starts along C;
- :mod:`~tactile_torch.svm.threads`: the thread count and a work queue the caller shares;
- :mod:`~tactile_torch.svm.tree`: the 2-means class tree of the HM-SVM;
- :mod:`~tactile_torch.svm._base`: what the two estimators share (validation, the solve along C,
  decision values on threads, ``predict_proba``);
- :mod:`~tactile_torch.svm.estimators`: :class:`SVC` (written in :mod:`~tactile_torch.svm._svc`) and
  :class:`HierarchicalSVC`;
- :mod:`~tactile_torch.svm.probability`: Platt scaling by internal cross-validation and the
  combination of binary probabilities (``probability=True``, ``predict_proba``);
- :mod:`~tactile_torch.svm.inference`: the inference graph (:class:`SVMInference`, exports to ONNX).

The batched model selection over C and gamma is :class:`tactile_torch.model_selection.SVMGridSearchCV`.

References
----------
C.-C. Chang, C.-J. Lin, "LIBSVM: a library for support vector machines", ACM TIST 2(3), 2011.
R.-E. Fan, P.-H. Chen, C.-J. Lin, "Working set selection using second order information for training
SVM", JMLR 6, 2005.
"""

from .._exports import lazy_exports

__getattr__, __dir__, __all__ = lazy_exports(
    __name__,
    {
        "estimators": ("SVC", "HierarchicalSVC"),
        "inference": (
            "SVMInference",
            "ovo_decisions",
            "ovo_votes",
            "path_scores",
            "svm_margins",
            "tree_descent",
        ),
        "kernels": ("KERNELS", "kernel_matrix", "scale_gamma"),
        "tree": ("TreeNode", "split_classes"),
    },
)
