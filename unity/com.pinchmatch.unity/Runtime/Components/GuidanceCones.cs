// Where to pinch: one cone per fingertip target, its tip on the target, lying along the grasp's
// line outside the object (as the match scenes draw them). Drawn where the fingers are seen: on the
// prop, or on the level's object when the hand is warped.
using System.Collections.Generic;
using UnityEngine;

namespace Pinchmatch.Unity
{
    public sealed class GuidanceCones : MonoBehaviour
    {
        public PropAnchor anchor;
        [Tooltip("A cone whose tip is at its origin, pointing along its +Z")]
        public GameObject conePrefab;

        readonly List<GameObject> cones = new List<GameObject>();

        void LateUpdate()
        {
            var placed = anchor != null ? anchor.Current : null;
            var seen = placed != null ? placed.SeenFingertipPositions : new Vec3[0];
            while (cones.Count < seen.Length && conePrefab != null)
                cones.Add(Instantiate(conePrefab, transform));
            for (int i = 0; i < cones.Count; i++)
            {
                bool shown = i < seen.Length;
                cones[i].SetActive(shown);
                if (!shown) continue;
                // toward the target from outside: from the other fingertips' middle through this one
                var others = Vec3.Zero;
                for (int k = 0; k < seen.Length; k++) if (k != i) others = others + seen[k];
                others = others / (seen.Length - 1);
                var inward = (others - seen[i]).Normalized;
                cones[i].transform.SetPositionAndRotation(UnityConvert.ToUnity(seen[i]),
                    Quaternion.LookRotation(UnityConvert.ToUnity(inward), Vector3.up));
            }
        }
    }
}
