// Is the user's grasp where the match says? XR Hands' ThumbTip, IndexTip (and MiddleTip) against the
// anchor's fingertip targets on the prop, within the study's 5 mm and 14 degrees, held 1 s. Either
// hand; a pinch's fingers in either order. Under the warp the real fingertips are judged against the
// prop's targets: the seen hand then meets the level's.
using System;
using UnityEngine;

namespace Pinchmatch.Unity
{
    public sealed class PinchValidator : MonoBehaviour
    {
        public PropAnchor anchor;
        [Tooltip("The XR Origin (the hand joints are relative to it)")]
        public Transform xrOrigin;
        public float positionToleranceMm = 5f;
        public float angleToleranceDeg = 14f;
        public float holdSeconds = 1f;

        /// <summary>Raised once per match when the grasp has held on target.</summary>
        public event Action<GraspCheck> Validated;

        public GraspCheck Last { get; private set; }

        HoldTimer timer;
        Placed placedFor;

        void Update()
        {
            var placed = anchor != null ? anchor.Current : null;
            var hands = HandJoints.Subsystem();
            if (placed == null || hands == null) return;
            if (timer == null || placedFor == null || placedFor.Virtual != placed.Virtual)
            {
                timer = new HoldTimer(holdSeconds);
                placedFor = placed;
            }
            var limits = new Limits(positionToleranceMm, angleToleranceDeg, holdSeconds);
            var targets = placed.FingertipPositions;
            bool ok = false;
            foreach (var hand in new[] { hands.leftHand, hands.rightHand })
            {
                var tips = HandJoints.Fingertips(hand, xrOrigin, targets.Length);
                if (tips == null) continue;
                var check = Validation.Check(tips, targets, limits);
                Last = check;
                ok |= check.Ok;
            }
            bool before = timer.Validated;
            timer.Update(ok, Time.time);
            if (!before && timer.Validated && Validated != null) Validated(Last);
        }
    }
}
