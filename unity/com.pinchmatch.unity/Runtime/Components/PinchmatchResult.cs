// A pinchmatch result in the scene: matches.json (a TextAsset) and, for a --placement fixed run,
// level.glb (imported as bytes: rename it level.glb.bytes, or give its path under StreamingAssets).
using System;
using System.IO;
using UnityEngine;

namespace Pinchmatch.Unity
{
    public sealed class PinchmatchResult : MonoBehaviour
    {
        [Tooltip("OUT/matches.json as a TextAsset")]
        public TextAsset matchesJson;
        [Tooltip("OUT/level.glb renamed level.glb.bytes (--placement fixed only)")]
        public TextAsset levelGlb;

        MatchesFile file;
        LevelFile level;

        /// <summary>The result, read once; null (with one error logged) where it cannot be read.</summary>
        public MatchesFile File
        {
            get
            {
                if (file == null && matchesJson != null) Load();
                return file;
            }
        }

        /// <summary>The level (a --placement fixed result), else null.</summary>
        public LevelFile Level
        {
            get
            {
                if (File == null) return null;
                return level;
            }
        }

        void Load()
        {
            try
            {
                file = MatchesFile.Parse(matchesJson.text);
                if (file.Placement == "fixed")
                {
                    if (levelGlb == null)
                        throw new InvalidDataException("a --placement fixed result needs its level.glb (as level.glb.bytes)");
                    level = LevelFile.Parse(LevelFile.GlbJson(levelGlb.bytes));
                }
            }
            catch (Exception e) when (e is JsonException || e is InvalidDataException)
            {
                Debug.LogError("pinchmatch: " + name + ": " + e.Message);
                file = null;
                level = null;
            }
        }

        /// <summary>The index of the match of the virtual object <paramref name="virtualName"/>,
        /// -1 where there is none.</summary>
        public int IndexOf(string virtualName)
        {
            var f = File;
            if (f == null) return -1;
            for (int i = 0; i < f.Matches.Count; i++) if (f.Matches[i].Virtual == virtualName) return i;
            return -1;
        }
    }
}
