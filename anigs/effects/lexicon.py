"""The words that name kinds of motion, by their dictionary form (lemma), in one place.

Only base forms are listed: plurals, inflections ("leaves", "flowering", "overgrown") reach them
through the lemmatizer (:mod:`anigs.effects.vocabulary`, ``lemminflect``), derived adjectives
("leafy", "grassy") through a suffix rule and compounds ("wildflower", "rosebush") through their
parts. Each entry names the regions (:data:`anigs.effects.config.REGIONS`) that move when the
prompt names it, including what the named subject implies: a flowering plant's blossoms move with
its leaves, so a flowering plant's name names ``foliage`` and ``flowers``.
"""
from __future__ import annotations

F, G, B, W = ("foliage",), ("grass",), ("flowers",), ("water",)
FB = ("foliage", "flowers")  # a flowering plant: its leaves and its blossoms
ALL = ("foliage", "grass", "flowers")  # a garden, a park

#: generic words: lemma -> regions
GENERIC: dict[str, tuple[str, ...]] = {
    **dict.fromkeys(("tree", "leaf", "foliage", "bush", "shrub", "hedge", "plant", "frond", "fern", "branch", "twig",
                     "bough", "palm", "ivy", "vine", "creeper", "climber", "canopy", "houseplant", "greenery",
                     "vegetation", "shrubbery", "thicket", "grove", "hedgerow", "undergrowth", "sapling", "conifer",
                     "evergreen", "bamboo", "overgrow", "verdant", "lush", "foliate", "stem", "stalk", "woods",
                     "wooded", "woodland", "treetop", "weeping willow", "horse chestnut", "palm tree", "leafage",
                     "verdure", "copse", "treeline", "seedling", "bonsai", "topiary", "bushland", "weed", "nettle",
                     "grapevine", "sagebrush", "windbreak"), F),
    **dict.fromkeys(("grass", "lawn", "meadow", "reed", "turf", "field", "prairie", "crop", "sedge", "hay",
                     "pasture", "savanna", "steppe", "grassland", "thistle"), G),
    **dict.fromkeys(("flower", "blossom", "bloom", "petal", "flowerbed", "flower bed", "bouquet", "floral", "posy"), B),
    **dict.fromkeys(("water", "pond", "lake", "river", "fountain", "sea", "ocean", "stream", "creek", "pool", "wave",
                     "ripple", "waterfall", "canal", "brook", "lagoon", "surf", "puddle", "rapids", "tide",
                     "estuary"), W),
    **dict.fromkeys(("marsh", "swamp", "wetland", "bog", "fen"), ("grass", "water")),
    **dict.fromkeys(("garden", "park", "backyard", "yard", "parkland"), ALL),
    **dict.fromkeys(("forest", "jungle", "orchard", "vineyard", "rainforest"), F),
    "greenhouse": FB,
}
#: scene words that head no compound ("courtyard", "graveyard" are no gardens)
SCENES = ("garden", "park", "backyard", "yard", "parkland")

#: nouns of made images and objects: the words after "of" ("a painting of trees") and a word of the lexicon
#: just before one ("rose wallpaper", "a leaf print") are depicted, not alive: they name nothing that moves
DEPICTIONS = frozenset(("painting", "picture", "photo", "photograph", "image", "drawing", "poster", "print", "mural",
                        "statue", "sculpture", "figurine", "carving", "illustration", "tapestry", "sketch", "postcard",
                        "wallpaper", "pattern", "motif", "replica", "fresco", "mosaic", "engraving", "etching",
                        "watercolour", "watercolor", "canvas", "sticker", "decal", "logo", "emblem", "embroidery",
                        "still life", "reflection"))
#: adjectives of made things: the words of the lexicon right after one ("plastic plants", "fake flowers",
#: "a painted tree") are no living plants; its reach ends at the first other noun ("a stone wall with ivy")
ARTIFICIAL = frozenset(("plastic", "fake", "artificial", "silk", "paper", "painted", "printed", "faux", "imitation",
                        "toy", "ceramic", "porcelain", "metal", "bronze", "marble", "carved", "embroidered", "stuffed",
                        "sculpted", "drawn", "pictured", "depicted", "dried", "wooden", "stone", "glass", "iron"))
#: motion verbs (lemmas): "not" before one ("the flowers must not move") switches off the words of the
#: lexicon before it in its clause; one without "not" ("the trees sway and ...") starts the reach anew
MOTION = frozenset(("move", "sway", "flutter", "wave", "ripple", "rustle", "blow", "dance", "bob", "swing", "shake",
                    "tremble", "quiver", "flow", "nod", "stir", "animate", "wiggle", "wobble", "bend", "toss"))
#: stillness after a verb of being or staying ("the walls and the flowers stay still", "the tree is
#: motionless"): switches off the words of the lexicon before it in its clause
STILLNESS = frozenset(("still", "static", "motionless", "frozen", "unmoving", "stationary", "rigid", "immobile",
                       "fixed", "steady"))
STAY = frozenset(("stay", "remain", "keep", "be", "stand", "sit", "hold", "look", "appear", "seem"))
#: what moves things: "no wind", "without any breeze" say the whole scene stays still (as does "nothing moves")
MOVERS = frozenset(("wind", "breeze", "gust", "motion", "movement", "animation"))
#: words that end the reach of a stillness or a negated motion backwards (and of a negation forwards)
CLAUSE = frozenset(("but", "while", "whereas", "although", "though", "yet", "except", "whilst"))

#: words understood as things that stay still (so they are not reported as not understood; they name no motion)
STILL = frozenset(("trunk", "bark", "stump", "log", "chateau", "facade", "planter", "pot", "french"))

#: plant names: lemma -> regions (trees and shrubs sway; flowering ones also bloom; grasses and crops wave)
PLANTS: dict[str, tuple[str, ...]] = {
    # trees and foliage plants
    **dict.fromkeys(("oak", "birch", "pine", "maple", "elm", "beech", "chestnut", "linden", "lime", "poplar",
                     "cypress", "cedar", "spruce", "fir", "larch", "yew", "olive", "eucalyptus", "acacia", "baobab",
                     "sycamore", "aspen", "alder", "hawthorn", "holly", "laurel", "cycad", "banana", "fig", "willow",
                     "hornbeam", "juniper", "redwood", "sequoia", "mangrove", "boxwood", "privet", "ficus", "monstera",
                     "philodendron", "hosta", "palmetto", "bracken", "ash", "walnut", "hazel", "rowan",
                     "ponderosa", "banyan", "tamarind", "pothos", "yucca", "citrus", "hemlock"), F),
    # flowering trees, shrubs and climbers: leaves and blossoms
    **dict.fromkeys(("magnolia", "cherry", "dogwood", "jacaranda", "rhododendron", "azalea", "hydrangea", "lilac",
                     "camellia", "hibiscus", "bougainvillea", "oleander", "wisteria", "jasmine", "gardenia",
                     "forsythia", "clematis", "honeysuckle", "rosebush", "lavender", "heather", "gorse",
                     "frangipani", "plumeria", "mimosa", "laburnum", "buddleia", "fuchsia", "vireya", "clivia",
                     "bromeliad"), FB),
    # flowers: the blossoms and the plant that carries them
    **dict.fromkeys(("rose", "tulip", "daisy", "sunflower", "lily", "orchid", "poppy", "peony", "dahlia", "marigold",
                     "geranium", "petunia", "pansy", "iris", "hollyhock", "foxglove", "lupin", "lupine", "daffodil",
                     "crocus", "hyacinth", "carnation", "chrysanthemum", "aster", "begonia", "zinnia", "snapdragon",
                     "dandelion", "buttercup", "bluebell", "anemone", "lotus", "wildflower", "cornflower", "primrose",
                     "delphinium", "gladiolus", "verbena", "salvia", "impatiens", "morning glory",
                     "water lily", "snowdrop", "bluebonnet", "edelweiss"), FB),
    # grasses and crops
    **dict.fromkeys(("wheat", "barley", "rye", "oat", "corn", "maize", "rice", "sorghum", "millet", "sugarcane",
                     "papyrus", "cattail", "bulrush", "pampas", "clover", "alfalfa", "cornfield", "wheatfield"), G),
}

#: verbs whose inflected forms name a kind ("flowering", "blooming", "overgrown"); other verbs are
#: not looked up as verbs ("waving" trees are not water)
VERBS = ("flower", "bloom", "blossom", "overgrow", "leaf", "sprout", "bud")

#: words that carry no meaning for what moves (left out of the words not understood)
FUNCTION_WORDS = frozenset("""a an the and or but nor of in on at by for with without from to into onto over under
above below beside besides between among amid around along across through behind before after near next its it
their his her my our your this that these those there here is are was were be been being has have had do does
some any all each every both either neither few many much more most several no not never very so too as than then
up down out off about against while when where which who whom whose what how why one two three four five
six seven eight nine ten s""".split())


def table() -> dict[str, tuple[str, ...]]:
    """Every listed term (one or two words, lemma) -> the regions it names."""
    return {**GENERIC, **PLANTS}
