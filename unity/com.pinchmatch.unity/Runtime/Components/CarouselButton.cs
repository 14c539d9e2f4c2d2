// The carousel's button beside a prop: a fingertip within `pressRadius` of it turns the carousel,
// the next object the carousel serves on this prop comes onto the prop (the anchor shows it); the
// fingertip must leave before the button presses again.
using UnityEngine;

namespace Pinchmatch.Unity
{
    public sealed class CarouselButton : MonoBehaviour
    {
        public PropAnchor anchor;
        [Tooltip("The prop's name in the result")]
        public string propName;
        public Transform xrOrigin;
        public float pressRadius = 0.03f;

        Carousel carousel;
        bool pressed;

        public int Turns { get; private set; }

        void Update()
        {
            if (anchor == null || anchor.result == null || anchor.result.File == null) return;
            if (carousel == null) carousel = new Carousel(anchor.result.File, propName);
            var hands = HandJoints.Subsystem();
            if (hands == null) return;
            bool near = false;
            var button = UnityConvert.ToCore(transform.position);
            foreach (var hand in new[] { hands.leftHand, hands.rightHand })
            {
                var tips = HandJoints.Fingertips(hand, xrOrigin, 2);
                if (tips == null) continue;
                foreach (var t in tips) near |= (t - button).Length < pressRadius;
            }
            if (near && !pressed) Press();
            pressed = near;
        }

        /// <summary>One turn of the carousel: the anchor shows the object now on the prop.</summary>
        public void Press()
        {
            int on = carousel.Turn();
            if (on < 0) return;
            Turns++;
            anchor.virtualName = anchor.result.File.Matches[on].Virtual;
        }
    }
}
