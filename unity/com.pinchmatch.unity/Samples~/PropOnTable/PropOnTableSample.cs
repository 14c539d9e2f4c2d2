// The sample's wiring in one component: put it on an empty GameObject, fill its fields (see
// README.md beside it), press Play. It adds the package's components and connects them.
using UnityEngine;

namespace Pinchmatch.Unity.Samples
{
    public sealed class PropOnTableSample : MonoBehaviour
    {
        [Tooltip("OUT/matches.json")]
        public TextAsset matchesJson;
        [Tooltip("OUT/level.glb renamed level.glb.bytes (--placement fixed only)")]
        public TextAsset levelGlb;
        [Tooltip("The tracked prop (its pose drives the anchor)")]
        public Transform trackedProp;
        [Tooltip("The virtual object to show first")]
        public string firstVirtual;
        [Tooltip("The virtual object's mesh (a match scene's `virtual` node, or the level's node)")]
        public Transform virtualObject;
        public Transform xrOrigin;
        public GameObject conePrefab;
        [Tooltip("The hand visual's root and the tracked root it follows (--placement fixed)")]
        public Transform handVisual, handTracked;
        [Tooltip("The carousel's button (--placement fixed); its prop's name in the result")]
        public Transform carouselButton;
        public string propName;

        void Awake()
        {
            var result = gameObject.AddComponent<PinchmatchResult>();
            result.matchesJson = matchesJson;
            result.levelGlb = levelGlb;
            var anchor = trackedProp.gameObject.AddComponent<PropAnchor>();
            anchor.result = result;
            anchor.virtualName = firstVirtual;
            anchor.virtualObject = virtualObject;
            var cones = gameObject.AddComponent<GuidanceCones>();
            cones.anchor = anchor;
            cones.conePrefab = conePrefab;
            var validator = gameObject.AddComponent<PinchValidator>();
            validator.anchor = anchor;
            validator.xrOrigin = xrOrigin;
            validator.Validated += check => Debug.Log("pinchmatch: " + anchor.virtualName + " held on target (" +
                                                      check.Order + ")");
            if (handVisual != null)
            {
                var warp = handVisual.gameObject.AddComponent<HandWarp>();
                warp.anchor = anchor;
                warp.xrOrigin = xrOrigin;
                warp.trackedRoot = handTracked;
            }
            if (carouselButton != null)
            {
                var button = carouselButton.gameObject.AddComponent<CarouselButton>();
                button.anchor = anchor;
                button.propName = propName;
                button.xrOrigin = xrOrigin;
            }
        }
    }
}
