// --placement fixed, a redirected object: the seen hand is moved by the warp (Warp.cs, the page's
// rule) so that it meets the level's object when the real hand meets the prop. Put it on the hand
// visual's root; `trackedRoot` is where the tracking puts that root unwarped.
using UnityEngine;

namespace Pinchmatch.Unity
{
    public sealed class HandWarp : MonoBehaviour
    {
        public PropAnchor anchor;
        public Transform xrOrigin;
        [Tooltip("The hand's root as tracked, unwarped")]
        public Transform trackedRoot;
        public bool rightHand = true;

        /// <summary>The offset applied this frame (metres, world).</summary>
        public Vector3 Offset { get; private set; }

        void LateUpdate()
        {
            var placed = anchor != null ? anchor.Current : null;
            var hands = HandJoints.Subsystem();
            Offset = Vector3.zero;
            if (placed != null && placed.Warped && hands != null)
            {
                var tips = HandJoints.Fingertips(rightHand ? hands.rightHand : hands.leftHand, xrOrigin,
                                                 placed.Fingertips.Length);
                if (tips != null)
                    Offset = UnityConvert.ToUnity(Warp.Offset(placed.HandStart, placed.PhysicalTarget,
                                                              placed.VirtualTarget, Vec3.Centroid(tips)));
            }
            if (trackedRoot != null) transform.SetPositionAndRotation(trackedRoot.position + Offset, trackedRoot.rotation);
        }
    }
}
