// On the tracked prop: shows the matched virtual object on it, registered (or brought by the
// carousel), and keeps its fingertip targets, in Unity's world, for the cones, the validator and the
// warp. Registered results: put it on the match scene's `tangible` node (or a prop whose mesh is
// that node's). --placement fixed: on the level's `pinchmatch_prop_NAME` node.
using UnityEngine;

namespace Pinchmatch.Unity
{
    public sealed class PropAnchor : MonoBehaviour
    {
        public PinchmatchResult result;
        [Tooltip("The virtual object whose match is shown (the carousel sets it)")]
        public string virtualName;
        [Tooltip("Its mesh: a match scene's `virtual` node (registered), or the level's own node")]
        public Transform virtualObject;
        [Tooltip("--placement fixed: where the level's root is (empty: the world's origin)")]
        public Transform levelRoot;

        /// <summary>The current match placed in Unity's world (null: none).</summary>
        public Placed Current { get; private set; }

        void LateUpdate()
        {
            Current = Place();
            if (Current != null && virtualObject != null) UnityConvert.Apply(virtualObject, Current.VirtualPose);
        }

        /// <summary>The match of <see cref="virtualName"/> on this prop where it stands now.</summary>
        public Placed Place()
        {
            if (result == null || result.File == null) return null;
            int i = result.IndexOf(virtualName);
            if (i < 0) return null;
            var match = result.File.Matches[i];
            if (match.Best == null) return null;
            var prop = UnityConvert.ToCore(transform);
            if (result.Level == null) return Placement.OnSceneProp(result.File, match, match.Best, prop);
            var root = levelRoot != null ? UnityConvert.ToCore(levelRoot) : Pinchmatch.Pose.Identity;
            return Placement.OnLevelProp(result.File, result.Level, match, prop, root);
        }
    }
}
